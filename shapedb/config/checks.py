"""Value checks shared by the configuration modules (:mod:`shapedb.config.core`, ...)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import Any, TypeVar

from shapedb.errors import ConfigError

__all__ = ["check", "is_int", "build_section"]

_C = TypeVar("_C")


def check(cond: bool, name: str, value: Any, why: str) -> None:
    """Raise :class:`ConfigError` ``"<name>=<value> is invalid: <why>"`` unless ``cond``."""
    if not cond:
        raise ConfigError(f"{name}={value!r} is invalid: {why}")


def is_int(x: Any) -> bool:
    """True for an ``int`` that is not a ``bool``."""
    return isinstance(x, int) and not isinstance(x, bool)


def build_section(cls: type[_C], data: Mapping[str, Any]) -> _C:
    """A configuration dataclass ``cls`` from a stored mapping of its fields.

    Raises
    ------
    ConfigError
        ``data`` is not a mapping, names a field ``cls`` does not have, or a value is out of
        range.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"cannot read {cls.__name__} from {data!r}: expected a mapping")
    known = {f.name for f in fields(cls)}  # type: ignore[arg-type]
    unknown = set(data) - known
    if unknown:
        raise ConfigError(f"unknown {cls.__name__} option(s): {sorted(unknown)}")
    return cls(**data)
