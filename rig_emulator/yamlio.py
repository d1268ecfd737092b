"""Reading the project's YAML data files with one-line errors that name the file."""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import yaml


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """A safe loader that reads plain scalars as YAML 1.2's core schema does (libyaml's
    parser where PyYAML has it: a 60,000-fault file took 29 s to read with the Python
    parser, a stranger's probe). YAML 1.1's forms changed values without a word (a
    stranger's probe with register numbers copied from a vendor sheet): ``010`` was octal
    (unit 8), ``1:10`` base 60 (address 70), ``on``/``yes`` true (a point named ``on``);
    ``1e12`` was text. Now: decimal integers (``0x``/``0o`` for hex and octal), floats with
    a dot or an exponent, ``.inf``/``.nan``, ``true``/``false``; anything else is text."""


_CORE = {
    "tag:yaml.org,2002:bool": (r"^(?:true|True|TRUE|false|False|FALSE)$", "tTfF"),
    "tag:yaml.org,2002:int": (r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$", "-+0123456789"),
    "tag:yaml.org,2002:float": (
        r"""^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$""",
        "-+0123456789.",
    ),
}
_NOT_CORE = ("tag:yaml.org,2002:timestamp",)  # (2024-05-01 was a date: a re-probe)
_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in entries if tag not in _CORE and tag not in _NOT_CORE]
    for first, entries in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
for _tag, (_pattern, _first) in _CORE.items():
    _Loader.add_implicit_resolver(_tag, re.compile(_pattern, re.X), list(_first))


def _core_int(loader: _Loader, node: yaml.ScalarNode) -> int:
    """An integer as YAML 1.2 reads it: decimal, or ``0x``/``0o`` (PyYAML's own took a
    leading 0 for octal)."""
    text = loader.construct_scalar(node)
    sign = -1 if text.startswith("-") else 1
    digits = text.lstrip("+-")
    if digits.startswith(("0x", "0o")):
        return sign * int(digits[2:], 16 if digits[1] == "x" else 8)
    return sign * int(digits)


_Loader.add_constructor("tag:yaml.org,2002:int", _core_int)


class _Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper, quoting every text this module would read as something else
    (a boiler named ``0o17`` was written bare and read back as the number 15: a re-probe)."""


def _represent_text(dumper: _Dumper, value: str) -> yaml.ScalarNode:
    try:
        bare = yaml.load(value, Loader=_Loader) == value
    except yaml.YAMLError:
        bare = False
    style = None if bare and value.strip() == value and value else '"'
    return dumper.represent_scalar("tag:yaml.org,2002:str", value, style=style)


_Dumper.add_representer(str, _represent_text)


def dump_yaml(data: Any) -> str:
    """``data`` as YAML that :func:`read_yaml` reads back as it is (keys in their order)."""
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True)


def _mapping_without_duplicates(loader: _Loader, node: yaml.MappingNode, deep: bool = False):
    """A mapping whose keys are unique: YAML 1.1 lets the last of two equal keys win
    silently (a boiler file with two ``p_nom_kW`` would use the second)."""
    seen: set[Any] = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue  # '<<: *base' merges; the mapping's own keys may override it
        key = loader.construct_object(key_node, deep=deep)
        if isinstance(key, Hashable):
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key '{key}' appears twice", key_node.start_mark
                )
            seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping_without_duplicates)


def finite_number(value: Any) -> float | None:
    """``value`` as a float if it is a finite number (an integer of hundreds of digits is
    not: it has no float, and ``math.isfinite`` raised OverflowError on it), else None;
    True and False are no numbers."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


#: The largest YAML set-up file read [bytes]: a register map of every Modbus unit and
#: register would be a few MB; a 20-MB map parsed for 90 s in 1.2 GB without a word, an
#: 8-MB boiler file 32 s before its error (a stranger's probe).
MAX_YAML_BYTES = 4_000_000


#: The most values a YAML set-up file may expand to, its aliases followed: a 551-byte
#: register map of aliases nested ten deep (a "billion laughs") ran 24 s in 2.5 GB where
#: its description was printed (a stranger's probe); every error message that shows a
#: value would do the same. The largest real file (MAX_YAML_BYTES) holds fewer.
MAX_YAML_VALUES = 2_000_000


def _within(data: Any, budget: int) -> bool:
    """Whether ``data`` holds at most ``budget`` values, aliases counted at every use (the
    walk stops at the budget, so a bomb costs no more than that)."""
    stack = [data]
    while stack:
        budget -= 1
        if budget < 0:
            return False
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.keys())
            stack.extend(item.values())
        elif isinstance(item, list | tuple | set):  # (!!pairs and !!omap make tuples,
            stack.extend(item)  # !!set a set: a re-probe's bomb went through them)
    return True


def read_yaml(path: Path, error: type[Exception]) -> Any:
    """The parsed content of ``path``; an unreadable file or bad YAML raises ``error`` with
    the file (and line) named."""
    try:
        if path.exists() and not path.is_file():  # (a device would be read forever)
            what = "a directory" if path.is_dir() else "not a regular file"
            raise error(f"{path}: {what}, not a set-up file")
        if path.is_file() and path.stat().st_size > MAX_YAML_BYTES:
            raise error(
                f"{path}: {path.stat().st_size / 1e6:.0f} MB, more than any set-up file of "
                f"this kind holds (at most {MAX_YAML_BYTES / 1e6:.0f} MB)"
            )
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = yaml.load(text, Loader=_Loader)  # a SafeLoader: no object construction
    except RecursionError:  # [[[[... a thousand deep
        raise error(f"{path}: not valid YAML (nested too deeply)") from None
    except ValueError as exc:  # an integer of more digits than Python converts (4300), or a
        if "digits" in str(exc) or "limit" in str(exc):  # tagged value: !!int abc
            raise error(f"{path}: not valid YAML (a number of thousands of digits)") from None
        raise error(f"{path}: not valid YAML (a value its !!tag cannot read)") from None
    except (KeyError, AttributeError, TypeError, IndexError):  # !!bool maybe, !!float ''
        # (tracebacks: probes)
        raise error(f"{path}: not valid YAML (a value its !!tag cannot read)") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None)
        if problem and "nesting depth" in problem:  # libyaml's own bound on [[[[...
            raise error(f"{path}: not valid YAML (nested too deeply)") from None
        why = f" ({problem})" if problem and "twice" in problem else ""
        if "single document" in (getattr(exc, "context", None) or ""):
            # (it said only the line: a stranger's probe)
            why = " (a second document starts there: a set-up file holds one; '---' begins another)"
        lines = text.splitlines()
        if mark is not None and mark.line < len(lines) and "\t" in lines[mark.line]:
            why = " (a tab: YAML indents with spaces)"  # (it said only the line: a probe)
        raise error(f"{path}: not valid YAML{where}{why}") from None
    if not _within(data, MAX_YAML_VALUES):
        raise error(
            f"{path}: its aliases (*name) expand to more than {MAX_YAML_VALUES:,} values, more "
            "than any set-up file of this kind holds"
        )
    return data


def resolve_named(name_or_path: str, folder: Path, kind: str, error: type[Exception]) -> Path:
    """A shipped file ``folder/NAME.yaml`` given by NAME, or a PATH to a YAML file; an
    unknown NAME raises ``error`` listing the known ones. A shipped NAME is the shipped
    file whatever the working directory holds (a folder ``clean`` there made every run
    fail with "clean: cannot read (Is a directory)", ``--profile`` given or not: a probe);
    ``./NAME`` names a file of that name."""
    path = Path(name_or_path)
    candidate = folder / f"{name_or_path}.yaml"
    bare = path.suffix not in (".yaml", ".yml") and "/" not in name_or_path
    if bare and name_or_path not in (".", "..") and candidate.is_file():
        return candidate
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    if not candidate.exists():
        known = ", ".join(sorted(p.stem for p in folder.glob("*.yaml")))
        raise error(f"unknown {kind} '{name_or_path}' (known: {known}, or a YAML path)")
    return candidate
