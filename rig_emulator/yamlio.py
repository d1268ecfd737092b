"""Reading the project's YAML data files with one-line errors that name the file."""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import yaml


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """YAML 1.1's safe loader, reading numbers as YAML 1.2 does: ``1e12`` and ``2E-3`` (no
    dot) are numbers, not text. libyaml's parser where PyYAML has it (a 60,000-fault file
    took 29 s to read with the Python parser: a stranger's probe)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


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


def read_yaml(path: Path, error: type[Exception]) -> Any:
    """The parsed content of ``path``; an unreadable file or bad YAML raises ``error`` with
    the file (and line) named."""
    try:
        if path.is_file() and path.stat().st_size > MAX_YAML_BYTES:
            raise error(
                f"{path}: {path.stat().st_size / 1e6:.0f} MB, more than any set-up file of "
                f"this kind holds (at most {MAX_YAML_BYTES / 1e6:.0f} MB)"
            )
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return yaml.load(text, Loader=_Loader)  # a SafeLoader: no object construction
    except RecursionError:  # [[[[... a thousand deep
        raise error(f"{path}: not valid YAML (nested too deeply)") from None
    except ValueError:  # an integer of more digits than Python converts (4300)
        raise error(f"{path}: not valid YAML (a number of thousands of digits)") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None)
        if problem and "nesting depth" in problem:  # libyaml's own bound on [[[[...
            raise error(f"{path}: not valid YAML (nested too deeply)") from None
        why = f" ({problem})" if problem and "twice" in problem else ""
        raise error(f"{path}: not valid YAML{where}{why}") from None


def resolve_named(name_or_path: str, folder: Path, kind: str, error: type[Exception]) -> Path:
    """A shipped file ``folder/NAME.yaml`` given by NAME, or a PATH to a YAML file; an
    unknown NAME raises ``error`` listing the known ones."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    candidate = folder / f"{name_or_path}.yaml"
    if not candidate.exists():
        known = ", ".join(sorted(p.stem for p in folder.glob("*.yaml")))
        raise error(f"unknown {kind} '{name_or_path}' (known: {known}, or a YAML path)")
    return candidate
