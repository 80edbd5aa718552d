"""``python -m copdea_fem.study``: print the README's table of the study keys;
``--stubs``: remake the type stub of the generated sections (``sections.pyi``)."""

import sys
from pathlib import Path

from copdea_fem.study.schema import reference_table

if sys.argv[1:] == ["--stubs"]:
    from copdea_fem.study.sections import stub_text
    stub = Path(__file__).with_name("sections.pyi")
    stub.write_text(stub_text())
    print(f"wrote {stub}")
else:
    print(reference_table())
