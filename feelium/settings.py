"""Typed, validated settings: the mechanism every config section is built on.

Each service declares its section as a frozen dataclass next to the code that
uses it, with every field made by :func:`setting` so that its default, its
allowed range and its one-line documentation live in one place. The loader in
:mod:`feelium.daemon.config` walks those dataclasses generically; nothing here knows
about any particular service.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Literal, get_args, get_origin, get_type_hints


class ConfigError(ValueError):
    """A config value is wrong: names the file, the dotted key and what was expected."""

    def __init__(self, source: str, key: str, message: str) -> None:
        super().__init__(f"{source}: {key}: {message}")
        self.source = source
        self.key = key
        self.message = message


def setting(
    default: Any,
    doc: str,
    *,
    min: float | None = None,
    max: float | None = None,
) -> Any:
    """A config field with its default, documentation and inclusive numeric range."""
    metadata = {"doc": doc, "min": min, "max": max}
    if isinstance(default, (list, dict, set)):
        raise TypeError("mutable defaults are not allowed in frozen settings; use a tuple")
    return field(default=default, metadata=metadata)


def section(cls: type) -> Any:
    """A nested section field whose default is the section's own defaults."""
    return field(default_factory=cls)


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is Literal:
        return " | ".join(repr(a) for a in get_args(tp))
    if origin in (types.UnionType, typing.Union):
        return " or ".join(_type_name(a) for a in get_args(tp))
    if origin is tuple:
        args = get_args(tp)
        return f"list of {_type_name(args[0])}" if args else "list"
    if tp is type(None):
        return "absent"
    return getattr(tp, "__name__", str(tp))


def _coerce(value: Any, tp: Any, key: str, source: str) -> Any:
    """Check ``value`` against annotation ``tp`` and return it in the dataclass's type."""
    origin = get_origin(tp)
    if origin in (types.UnionType, typing.Union):
        errors = []
        for option in get_args(tp):
            if option is type(None):
                continue
            try:
                return _coerce(value, option, key, source)
            except ConfigError as exc:
                errors.append(exc.message)
        raise ConfigError(source, key, f"expected {_type_name(tp)}, got {value!r}")
    if origin is Literal:
        if value not in get_args(tp):
            raise ConfigError(source, key, f"expected one of {_type_name(tp)}, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(source, key, f"expected {_type_name(tp)}, got {value!r}")
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0], f"{key}[{i}]", source) for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(source, key, f"expected {len(args)} values, got {len(value)}")
        return tuple(_coerce(v, a, f"{key}[{i}]", source) for i, (v, a) in enumerate(zip(args, value)))
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(source, key, f"expected true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(source, key, f"expected an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(source, key, f"expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(source, key, f"expected a finite number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(source, key, f"expected a string, got {value!r}")
        return value
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(source, key, f"expected a table [{key}], got {value!r}")
        return build_section(tp, value, source, key)
    raise TypeError(f"unsupported setting type {tp!r} at {key}")


def _check_range(value: Any, meta: typing.Mapping[str, Any], key: str, source: str) -> None:
    lo, hi = meta.get("min"), meta.get("max")
    if lo is None and hi is None:
        return
    items = value if isinstance(value, tuple) else (value,)
    for item in items:
        if not isinstance(item, (int, float)):
            continue
        if (lo is not None and item < lo) or (hi is not None and item > hi):
            bounds = f"[{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
            raise ConfigError(source, key, f"{item!r} is out of range {bounds}")


def build_section(cls: type, table: dict[str, Any], source: str, prefix: str = "") -> Any:
    """Build dataclass ``cls`` from a TOML table, rejecting unknown keys and bad values."""
    hints = get_type_hints(cls)
    known = {f.name: f for f in dataclasses.fields(cls)}
    retired: dict[str, str] = getattr(cls, "RETIRED_KEYS", {})
    for name in table:
        if name not in known:
            where = f"{prefix}.{name}" if prefix else name
            if name in retired:  # a key an older config may still carry: say why it went, not just that it is unknown
                raise ConfigError(source, where, f"this key was removed: {retired[name]}; delete it from the config")
            raise ConfigError(source, where, f"unknown key; known keys: {', '.join(sorted(known))}")
    kwargs: dict[str, Any] = {}
    for name, fld in known.items():
        if name not in table:
            continue
        key = f"{prefix}.{name}" if prefix else name
        value = _coerce(table[name], hints[name], key, source)
        _check_range(value, fld.metadata, key, source)
        kwargs[name] = value
    try:
        instance = cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise ConfigError(source, prefix or "(root)", str(exc)) from exc
    return instance


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        return f'"{escaped}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot render {value!r} as TOML")


def render_toml(instance: Any, prefix: str = "", *, comments: bool = True) -> str:
    """Render a settings dataclass as documented TOML that loads back to the same values."""
    scalars: list[str] = []
    tables: list[str] = []
    hints = get_type_hints(type(instance))
    for fld in dataclasses.fields(instance):
        value = getattr(instance, fld.name)
        key = f"{prefix}.{fld.name}" if prefix else fld.name
        if dataclasses.is_dataclass(value):
            header = f"[{key}]"
            doc = (type(value).__doc__ or "").strip().splitlines()
            block = []
            if comments and doc:
                block.append(f"# {doc[0]}")
            block.append(header)
            body = render_toml(value, key, comments=comments)
            tables.append("\n".join(block) + ("\n" + body.rstrip("\n") if body.strip() else ""))
            continue
        if comments:
            doc = fld.metadata.get("doc", "")
            lo, hi = fld.metadata.get("min"), fld.metadata.get("max")
            extra = ""
            if lo is not None or hi is not None:
                extra = f" Range: {'-inf' if lo is None else lo} .. {'inf' if hi is None else hi}."
            origin = get_origin(hints[fld.name])
            if origin is Literal:
                extra += f" One of: {_type_name(hints[fld.name])}."
            if doc or extra:
                scalars.append(f"# {doc}{extra}".rstrip())
        if value is None:
            scalars.append(f"# {fld.name} = (unset)")
        else:
            scalars.append(f"{fld.name} = {_toml_value(value)}")
    parts = []
    if scalars:
        parts.append("\n".join(scalars))
    parts.extend(tables)
    return "\n\n".join(p.rstrip("\n") for p in parts) + ("\n" if parts else "")


__all__ = ["ConfigError", "build_section", "dataclass", "render_toml", "section", "setting"]
