"""Option values checked against their allowed ranges.

Each options dataclass lists its fields' ranges in ``LIMITS`` (``"> 0"``, ``"[0, 1)"``,
``"0 or >= 3"``, …) and calls :func:`check_limits` from ``__post_init__``; a float field is
always refused when it is not finite (NaN would pass every comparison as False). Code that
changes a field after construction (the CLI, a caller's script) is caught by
:func:`validate`, which the pipeline runs on all its options before any long work.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from .errors import InputError


class OptionError(InputError):
    """An option outside its allowed range: ``name=value but expected …``."""

    def __init__(self, name: str, value: Any, expected: str) -> None:
        self.name, self.value, self.expected = name, value, expected
        super().__init__(f"{name}={value!r} but expected {expected}")

    def within(self, section: str) -> OptionError:
        """The same error named by its place in the options (``verify.tolerance_px``)."""
        return OptionError(f"{section}.{self.name}", self.value, self.expected)


_INTERVAL = re.compile(r"^([\[(])\s*(\S+)\s*,\s*(\S+)\s*([\])])$")
_BOUND = re.compile(r"^(>=|>|<=|<)\s*(\S+)$")


def _allows(rule: str, value: float) -> bool:
    """Whether ``value`` satisfies ``rule``: intervals ``[a, b)``, bounds ``> a``, single
    values, joined by ``or``."""
    for part in rule.split(" or "):
        part = part.strip()
        if m := _INTERVAL.match(part):
            lo, hi = float(m[2]), float(m[3])
            if (value >= lo if m[1] == "[" else value > lo) and (
                value <= hi if m[4] == "]" else value < hi
            ):
                return True
        elif m := _BOUND.match(part):
            b = float(m[2])
            if {">=": value >= b, ">": value > b, "<=": value <= b, "<": value < b}[m[1]]:
                return True
        elif value == float(part):
            return True
    return False


def check_limits(obj: Any) -> None:
    """Raise :class:`OptionError` for the first field of the options dataclass ``obj`` that is
    a non-finite float or outside its range in ``type(obj).LIMITS`` (None always passes: it
    means "not given")."""
    limits: dict[str, str] = getattr(type(obj), "LIMITS", {})
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is None or isinstance(value, bool) or not isinstance(value, int | float):
            continue
        if isinstance(value, float) and not math.isfinite(value):
            raise OptionError(f.name, value, "a finite number")
        rule = limits.get(f.name)
        if rule is not None and not _allows(rule, value):
            raise OptionError(f.name, value, rule)


def validate(options: Any, section: str = "") -> None:
    """Check ``options`` and every options dataclass inside it again (their ``__post_init__``:
    ranges and the checks between fields), naming a bad value by its place
    (``verify.tolerance_px``). Nothing is changed."""
    try:
        post = getattr(options, "__post_init__", None)
        if post is not None:
            post()
        else:
            check_limits(options)
    except OptionError as e:
        raise (e.within(section) if section else e) from None
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            validate(value, f"{section}.{f.name}" if section else f.name)
