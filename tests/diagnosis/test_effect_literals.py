"""Each effect is described once: no effect identifier is written outside the catalogue.

The other modules read an :class:`~copdea_fem.diagnosis.effects.Effect`'s fields; a
string literal equal to an effect id anywhere else in ``copdea_fem/`` means a rule about
that effect lives outside its description.  Docstrings and ``__all__`` (which names Python
objects) are not code about an effect.  Outside ``copdea_fem/diagnosis/`` an id that is
also a word of the study file (``baffle``: a ``geometry.frame`` value; ``enclosure``: a
``geometry`` key) means that word, and is allowed there.
"""

import ast
from pathlib import Path

import copdea_fem
from copdea_fem.diagnosis.effects import EFFECT_IDS
from copdea_fem.study import SCHEMA

PACKAGE = Path(copdea_fem.__file__).parent
CATALOGUE_FILE = PACKAGE / "diagnosis" / "effects.py"
DIAGNOSIS = PACKAGE / "diagnosis"


def study_words() -> set:
    """Section and key names of the study file and the values its keys allow."""
    words = set(SCHEMA)
    for keys in SCHEMA.values():
        for name, key in keys.items():
            words.add(name)
            words.update(str(choice) for choice in (key.choices or ()))
    return words


def effect_literals(source: str, ids) -> list:
    """``(line, id)`` of every string constant of ``source`` equal to one of ``ids``,
    docstrings and ``__all__`` entries left out."""
    tree = ast.parse(source)
    ignored = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                ignored.add(id(first.value))
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
                ignored.update(id(c) for c in ast.walk(node.value))
    return sorted((node.lineno, node.value) for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and node.value in ids and id(node) not in ignored)


def test_the_scan_finds_a_literal_and_skips_docstrings_and_all():
    source = ('"""air_loading in a docstring."""\n__all__ = ["modal_damping"]\n'
              'def f():\n    """baffle."""\n    return "air_loading", "baffle ok"\n')
    assert effect_literals(source, {"air_loading", "modal_damping", "baffle"}) == [
        (5, "air_loading")]


def test_no_effect_id_is_written_outside_the_catalogue():
    ids = set(EFFECT_IDS)
    study_ids = ids & study_words()
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path == CATALOGUE_FILE:
            continue
        forbidden = ids if DIAGNOSIS in path.parents else ids - study_ids
        found += [f"{path.relative_to(PACKAGE.parent)}:{line}: {value!r}"
                  for line, value in effect_literals(path.read_text(), forbidden)]
    assert not found, ("effect ids written outside copdea_fem/diagnosis/effects.py (read the "
                       "Effect's fields instead):\n" + "\n".join(found))
