"""The one error type for bad input: it names the field, the value and what is allowed."""

from __future__ import annotations


class InputError(ValueError):
    """Raised for any user-supplied value that is missing, malformed or out of range.

    The message is one line, ``<field> = <value>: <what is allowed>``, fit for a log line
    or a command-line error, so callers never have to show a traceback.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field} = {value!r}: {allowed}")


def require_finite(field: str, value: object) -> float:
    """Return ``value`` as a float, or raise InputError if it is not a finite number."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(field, value, "must be a finite number") from None
    if isinstance(value, bool) or number != number or number in (float("inf"), float("-inf")):
        raise InputError(field, value, "must be a finite number")
    return number


def require_range(
    field: str,
    value: object,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    unit: str = "",
) -> float:
    """Return ``value`` as a float within [low, high] (``(low, high]`` if low_open).

    Any failure, a NaN or a string included, names the allowed range.
    """
    suffix = f" {unit}" if unit else ""
    if high is None and low is None:
        allowed = "must be a finite number"
    elif high is None:
        allowed = f"must be {'>' if low_open else '>='} {low:g}{suffix}"
    elif low is None:
        allowed = f"must be <= {high:g}{suffix}"
    else:
        allowed = f"must be in {'(' if low_open else '['}{low:g}, {high:g}]{suffix}"
    try:
        number = require_finite(field, value)
    except InputError:
        raise InputError(field, value, allowed if allowed.endswith("finite number") else f"{allowed} (a finite number)") from None
    too_low = low is not None and (number <= low if low_open else number < low)
    too_high = high is not None and number > high
    if too_low or too_high:
        raise InputError(field, value, allowed)
    return number
