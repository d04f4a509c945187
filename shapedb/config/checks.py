"""Value checks shared by the configuration modules (:mod:`shapedb.config.core`, ...)."""

from __future__ import annotations

from typing import Any

from shapedb.errors import ConfigError

__all__ = ["check", "is_int"]


def check(cond: bool, name: str, value: Any, why: str) -> None:
    """Raise :class:`ConfigError` ``"<name>=<value> is invalid: <why>"`` unless ``cond``."""
    if not cond:
        raise ConfigError(f"{name}={value!r} is invalid: {why}")


def is_int(x: Any) -> bool:
    """True for an ``int`` that is not a ``bool``."""
    return isinstance(x, int) and not isinstance(x, bool)
