"""Strict reading of input files: study, sweep and measured YAML, CSV and JSON data.

Every input file is read whole through :func:`read_text`, which refuses, each
with its own one-line message, a path that does not exist, a folder, something
that is not a regular file (a FIFO, ``/dev/zero``), a file that cannot be read,
one above the size limit, a binary file (a NUL byte), text that is not UTF-8
and an empty file.  YAML is parsed by :class:`StrictLoader`: PyYAML's safe
loader, which also refuses a key given twice in one mapping (naming both
lines) and any anchor or alias (``&a`` / ``*a``): an alias "bomb" of a few
lines would otherwise expand to gigabytes, and a study that says one thing in
two places is ambiguous.  Refusals happen while parsing, at the first offending
token, so they take milliseconds.

Values echoed in messages go through :func:`preview`, which cuts them to a
short prefix.
"""

from __future__ import annotations

import os
from pathlib import Path, PurePath

import yaml

#: Largest study, sweep or measured.yaml file [bytes]; the bundled ones are below 3 KB.
MAX_YAML_BYTES = 1 << 20
#: Largest CSV or JSON data file [bytes]: a 100000-line spectrum is ~6 MB.
MAX_DATA_BYTES = 64 << 20
PREVIEW_CHARACTERS = 60
#: Paths are shown whole up to this length.
PATH_CHARACTERS = 500


def preview(value, width: int = PREVIEW_CHARACTERS) -> str:
    """``repr(value)``, cut to ``width`` characters with the full length noted.

    A path (:class:`pathlib.PurePath`) is shown whole up to :data:`PATH_CHARACTERS`
    (whatever ``width``); a longer one keeps its file name whole: the folder part is cut
    instead (:func:`preview_path`).
    """
    if isinstance(value, PurePath):
        return preview_path(value, max(width, PATH_CHARACTERS))
    text = repr(value)
    if len(text) <= width:
        return text
    return f"{text[:width]}... ({len(text)} characters)"


def preview_path(path, width: int = PREVIEW_CHARACTERS) -> str:
    """``repr(str(path))``; above ``width`` characters the start of the folder part and the
    whole file name, ``'/work/runs/...a/z16_v2_resonance.csv' (74 characters)``."""
    text = str(path)
    if len(repr(text)) <= width:
        return repr(text)
    name = PurePath(text).name or text
    head = text[:len(text) - len(name)]
    keep = max(0, width - len(name) - 6)          # quotes, "..." and a separator
    return f"{repr(head[:keep] + '...' + os.sep + name)} ({len(text)} characters)"


def as_path(path, what: str, error: type[Exception] = ValueError) -> Path:
    """``path`` (text or path-like) as a :class:`~pathlib.Path`, or ``error`` naming
    ``what`` where it is no path at all (a number, None, a list)."""
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"{what} = {preview(path)} is not allowed; allowed: a file's path")
    return Path(path)


def read_text(path: str | Path, what: str, limit: int = MAX_DATA_BYTES,
              error: type[Exception] = ValueError) -> str:
    """The UTF-8 text of an input file, or ``error`` with a one-line message.

    ``what`` names the file in the message (``"study file"``, ``"conditions[0].spectrum"``):
    ``study file = 'x.yaml' is not allowed (a binary file); allowed: a UTF-8 text file ...``.
    """
    path = as_path(path, what, error)

    def refuse(reason):
        return error(f"{what} = {preview(path, PATH_CHARACTERS)} is not allowed ({reason}); "
                     f"allowed: a UTF-8 text file of at most {limit} bytes")

    try:
        if not path.exists():
            raise refuse("does not exist")
        if path.is_dir():
            raise refuse("a folder, not a file")
        if not path.is_file():
            raise refuse("not a regular file")
        size = path.stat().st_size
        if size > limit:
            raise refuse(f"{size} bytes, above the limit")
        data = path.read_bytes()
    except OSError as exc:
        raise refuse(f"cannot be read: {exc.strerror or exc}") from None
    if b"\0" in data:
        raise refuse("a binary file")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise refuse(f"not UTF-8 text: byte 0x{data[exc.start]:02x} at offset {exc.start}") \
            from None
    if not text.strip():
        raise refuse("empty file")
    return text


class StrictLoader(yaml.SafeLoader):
    """SafeLoader refusing anchors, aliases and duplicate keys (see the module doc)."""

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
            raise yaml.constructor.ConstructorError(
                None, None, f"anchors and aliases (&{event.anchor}, *{event.anchor}) are not "
                "allowed; write the value out", event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                first = seen.get(key)
            except TypeError:        # an unhashable key: SafeLoader reports it below
                continue
            if first is not None:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {preview(key)} is given twice, on lines {first} and "
                    f"{key_node.start_mark.line + 1}; keep one", key_node.start_mark)
            seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


def parse_yaml(text: str, where: str, error: type[Exception] = ValueError):
    """YAML text -> Python data with :class:`StrictLoader`; ``error`` names ``where``."""
    try:
        return yaml.load(text, Loader=StrictLoader)
    except ValueError as exc:       # an integer of more than 4300 digits (Python's limit)
        raise error(f"{where} is not valid YAML: {exc}") from None
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or str(exc)
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        raise error(f"{where} is not valid YAML{at}: {problem}") from None


def read_yaml(path: str | Path, what: str, error: type[Exception] = ValueError):
    """:func:`read_text` + :func:`parse_yaml` with the YAML size limit; a mapping or error."""
    path = Path(path)
    shown = preview(path, PATH_CHARACTERS)
    raw = parse_yaml(read_text(path, what, MAX_YAML_BYTES, error), f"{what} {shown}", error)
    if raw is None:
        raise error(f"{what} = {shown} is not allowed (only comments); allowed: a mapping of "
                    "keys")
    if not isinstance(raw, dict):
        raise error(f"{what} {shown} must hold a mapping of keys, got "
                    f"{type(raw).__name__}")
    return raw
