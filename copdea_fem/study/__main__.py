"""``python -m copdea_fem.study``: print the README's table of the study keys."""

from copdea_fem.study.schema import reference_table

print(reference_table())
