"""The one error type for bad input: it names the field, the value and what is allowed; and the
checks of user input that raise it (numbers in range, output paths that are no links)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO

ECHO_CHARS = 80  # most characters of a bad value a message repeats (a hostile 1 MB value is cut)


def shorten(value: object, limit: int = ECHO_CHARS) -> str:
    """``repr(value)``, cut to ``limit`` characters plus "… (N chars)" when longer.

    repr escapes what a log cannot print (control characters, lone surrogates), so the
    result is always one printable line; a container is cut before its repr is built whole.
    """
    if isinstance(value, (str, bytes)) and len(value) > 4 * limit:
        text = repr(value[: 4 * limit])
        total = len(value)
        return f"{text[:limit]}… ({total} chars)"
    try:
        text = repr(value)
    except (
        RecursionError,
        ValueError,
    ):  # a structure nested too deep, an int past the digit limit
        return f"<{type(value).__name__}>"
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} chars)"


class InputError(ValueError):
    """Raised for any user-supplied value that is missing, malformed or out of range.

    The message is one line, ``<field> = <value>: <what is allowed>``, fit for a log line
    or a command-line error, so callers never have to show a traceback.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field} = {shorten(value)}: {allowed}")


def require_finite(field: str, value: object, *, allow_text: bool = True) -> float:
    """Return ``value`` as a float, or raise InputError if it is not a finite number.

    ``allow_text`` False refuses a string however numeric it looks (a JSON command's
    ``"0.03"`` is text, not a number); True takes command-line text.
    """
    if not allow_text and isinstance(value, (str, bytes)):
        raise InputError(field, value, "must be a finite number")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int of 400 digits
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
    allow_text: bool = True,
) -> float:
    """Return ``value`` as a float within [low, high] (``(low, high]`` if low_open).

    Any failure, a NaN or a string included, names the allowed range. ``allow_text`` False
    refuses strings (see :func:`require_finite`).
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
        number = require_finite(field, value, allow_text=allow_text)
    except InputError:
        what = (
            "a number, not text"
            if isinstance(value, str) and not allow_text
            else "a finite number"
        )
        raise InputError(
            field, value, allowed if allowed.endswith("finite number") else f"{allowed} ({what})"
        ) from None
    too_low = low is not None and (number <= low if low_open else number < low)
    too_high = high is not None and number > high
    if too_low or too_high:
        raise InputError(field, value, allowed)
    return number


def require_section(field: str, value: object) -> Mapping[str, Any]:
    """Return the parameter section ``value`` (None, absent: an empty one), or raise InputError
    naming the field when it is something else (a number or text where names and values go)."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise InputError(
            field,
            value,
            "must be a parameter section (names with their values), not a single value",
        )
    return value


def require_int(field: str, value: object, low: int | None = None, high: int | None = None) -> int:
    """Return ``value``, an integer within [low, high] (either bound optional), or raise
    InputError naming the field and the allowed range (a bool, a float or a string is refused)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or (low is not None and value < low)
        or (high is not None and value > high)
    ):
        if low is not None and high is not None:
            allowed = f"must be an integer in [{low}, {high}]"
        elif low is not None:
            allowed = f"must be an integer >= {low}"
        elif high is not None:
            allowed = f"must be an integer <= {high}"
        else:
            allowed = "must be an integer"
        raise InputError(field, value, allowed)
    return value


def require_new_path(field: str, path: object) -> Path:
    """Return ``path`` as a Path that names nothing yet, for a directory a command creates (a bag).

    Refuses an existing path and any symbolic link, a dangling one included: writing through a
    link would put the output wherever the link points.
    """
    target = Path(str(path))
    if target.is_symlink():
        raise InputError(
            field,
            str(target),
            f"is a symbolic link (to {_link_text(target)}): give a new path, not a link",
        )
    if target.exists():
        raise InputError(field, str(target), "must not exist yet (a new one is written)")
    return target


def require_output_file(field: str, path: object) -> Path:
    """Return ``path`` as a Path a command may (over)write as a regular file (a figure, a JSON).

    A regular file there is replaced; a symbolic link (dangling or not) or a directory is
    refused, so that nothing outside the named path is ever overwritten through a link.
    """
    target = Path(str(path))
    if target.is_symlink():
        raise InputError(
            field,
            str(target),
            f"is a symbolic link (to {_link_text(target)}): refusing to write through it",
        )
    if target.is_dir():
        raise InputError(field, str(target), "is a directory: give a file name")
    if target.parent.exists() and not target.parent.is_dir():
        raise InputError(field, str(target), f"its folder {target.parent} is not a directory")
    return target


def _link_text(link: Path) -> str:
    try:
        return repr(os.readlink(link))
    except OSError:
        return "?"


def open_output_file(field: str, path: object) -> BinaryIO:
    """Open ``path`` for writing as :func:`require_output_file` allows, refusing a link that
    appears in between too (``O_NOFOLLOW``): the caller writes and closes it."""
    target = require_output_file(field, path)
    try:
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        raise InputError(
            field, str(target), f"cannot be written ({exc.strerror or exc})"
        ) from None
    return os.fdopen(fd, "wb")
