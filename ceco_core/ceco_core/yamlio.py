"""YAML documents read with libyaml's safe loader when PyYAML has it (10x faster), else PyYAML's own.

The frozen benchmark files and the model parameter files are read on every run; ``CSafeLoader`` builds the
same Python objects as ``SafeLoader`` (baselines.yaml 158 -> 15 ms, the model's parameters 6.4 -> 0.75 ms).
"""

from __future__ import annotations

import yaml

__all__ = ["safe_load", "load_file", "error_text", "UniqueKeyLoader"]

_BASE = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_MERGE_TAG = "tag:yaml.org,2002:merge"


class UniqueKeyLoader(_BASE):  # type: ignore[misc, valid-type]
    """The safe loader, refusing a mapping that gives one key twice.

    YAML 1.2 requires keys to be unique; PyYAML keeps the last value without a word, so a scenario with two
    ``duration_s:`` lines silently ran the second. A merge (``<<: *base``) followed by one of its keys is an
    override, not a duplicate.

    Each mapping is checked as written, the first time the constructor flattens it: when it is built, or
    earlier when another mapping merges it (PyYAML flattens a merged mapping in place, so a check at
    construction would see the merged keys beside their overrides).
    """

    def flatten_mapping(self, node):
        """Check ``node``'s own keys (once), then PyYAML's merge flattening."""
        checked = self.__dict__.setdefault("_ceco_checked", set())
        if id(node) not in checked:
            checked.add(id(node))
            _check_unique_keys(self, node)
        super().flatten_mapping(node)


def _check_unique_keys(loader, node) -> None:
    """ConstructorError at the second occurrence of a key among ``node``'s own (merge keys aside)."""
    seen: dict = {}
    for key_node, _ in node.value:
        if key_node.tag == _MERGE_TAG:
            continue
        key = loader.construct_object(key_node, deep=True)
        try:
            first = seen.setdefault(key, key_node.start_mark)
        except TypeError:  # an unhashable key: the constructor says so
            continue
        if first is not key_node.start_mark:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping",
                node.start_mark,
                f"found the key {key!r} twice (first at line {first.line + 1})",
                key_node.start_mark,
            )


_LOADER = UniqueKeyLoader


def safe_load(stream):
    """``yaml.safe_load`` of a string or an open file, with libyaml where available.

    A key given twice in one mapping is a ``yaml.YAMLError`` (:class:`UniqueKeyLoader`).
    """
    return yaml.load(stream, Loader=_LOADER)


def load_file(path) -> object:
    """The YAML document in the file ``path``; ValueError naming the file for text that is not YAML or not UTF-8.

    A configuration file with a YAML error (an unclosed bracket, a bad indent) or binary content is the user's
    mistake: one line with the file and where it broke, not a parser traceback. OSError (a missing file) passes.
    """
    import pathlib

    p = pathlib.Path(path)
    try:
        return safe_load(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{p}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{p}: not valid YAML{error_text(exc)}") from None


def os_error_words(exc: OSError, wanted: str) -> str:
    """Why a file could not be read, in words (not Python's ``[Errno 21] Is a directory: ...``).

    ``wanted``: what the user should give instead of a directory (e.g. ``the grid YAML file``).
    """
    if isinstance(exc, IsADirectoryError):
        return f"a directory: give {wanted}"
    if isinstance(exc, FileNotFoundError):
        return "not found"
    return f"cannot be read ({exc.strerror})"


def error_text(exc: yaml.YAMLError) -> str:
    """A YAML error in one line: ``" at line L, column C: problem"`` (PyYAML's own text spans several lines)."""
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return f"{where}: {problem}"
