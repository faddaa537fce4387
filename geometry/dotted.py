"""Dotted-path access to frozen design dataclasses (``"horn.length"``, ``"segments.rod.length"``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from rpud_common import ParameterError

__all__ = ["child_named", "replace_path", "radial_signature"]


def child_named(obj: Any, key: str, path: str) -> Any:
    """The field ``key`` of a dataclass, or the item named ``key`` (or at index ``key``) of a tuple;
    ``path`` names it in the error."""
    if isinstance(obj, tuple):
        for item in obj:
            if getattr(item, "name", None) == key:
                return item
        if key.isdigit() and int(key) < len(obj):
            return obj[int(key)]
        raise ParameterError(path, key, "unknown item; known: " + ", ".join(str(getattr(i, "name", i)) for i in obj))
    if not dataclasses.is_dataclass(obj) or key not in {f.name for f in dataclasses.fields(obj)}:
        allowed = ", ".join(f.name for f in dataclasses.fields(obj)) if dataclasses.is_dataclass(obj) else "none"
        raise ParameterError(path, key, f"unknown parameter; allowed here: {allowed}")
    return getattr(obj, key)


def replace_path(obj: Any, keys: list[str], value: Any, path: str) -> Any:
    """A copy of ``obj`` with the value at the dotted ``keys`` replaced by ``value``."""
    key = keys[0]
    if isinstance(obj, tuple):
        child = child_named(obj, key, path)
        idx = obj.index(child)
        new_child = replace_path(child, keys[1:], value, path) if len(keys) > 1 else value
        return obj[:idx] + (new_child,) + obj[idx + 1:]
    child = child_named(obj, key, path)
    if len(keys) > 1:
        return dataclasses.replace(obj, **{key: replace_path(child, keys[1:], value, path)})
    if key == "kind":
        raise ParameterError(path, value, "the design kind cannot be replaced")
    hint = type(child) if child is not None else None
    if isinstance(child, float) and isinstance(value, (int, np.integer, np.floating)) and not isinstance(value, bool):
        value = float(value)
    elif hint is int and isinstance(value, float) and value.is_integer():
        value = int(value)
    return dataclasses.replace(obj, **{key: value})


def radial_signature(design) -> list:
    """Every non-tunable value of the design (used to refuse an inexact morph)."""
    tun = set(design.tunable_lengths())
    flat = _flatten(design.to_mapping(), "")
    return sorted((k, repr(v)) for k, v in flat.items() if k not in tun and k != "name")


def _flatten(obj: Any, prefix: str) -> dict:
    out = {}
    if isinstance(obj, Mapping):
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(obj, list) and obj and isinstance(obj[0], Mapping):
        for i, v in enumerate(obj):
            out.update(_flatten(v, f"{prefix}.{v.get('name', i)}"))
    else:
        out[prefix] = obj
    return out
