"""The ``impact_cmd`` wire format: one JSON object, bounded before it is parsed
(docs/interface.md).

A command comes from any participant of the ROS domain, so its text is checked before
``json.loads`` sees it: at most ``MAX_COMMAND_CHARS`` characters, nested at most
``MAX_NESTING`` deep (a JSON nested 100 000 deep would otherwise end in a RecursionError), and
integers of more than ``MAX_INT_DIGITS`` digits become floats (inf beyond 1e308) so that the
range check refuses them by name instead of ``int()`` failing on its digit limit. Every
failure is an :class:`~tail_beam_sim.errors.InputError` naming ``impact_cmd``.
"""

from __future__ import annotations

import json
from typing import Any

from tail_beam_sim.errors import InputError

MAX_COMMAND_CHARS = 4096  # a valid command is about 120 characters
MAX_NESTING = 4  # a valid command is one flat object (depth 1)
MAX_INT_DIGITS = 30


def _parse_int(digits: str) -> int | float:
    """A JSON integer; one too long for an ``int`` is a float (``inf`` past 1e308)."""
    return int(digits) if len(digits.lstrip("-")) <= MAX_INT_DIGITS else float(digits)


def nesting_depth(text: str) -> int:
    """How deep ``[`` and ``{`` nest in JSON text, outside strings (linear scan)."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def parse_command(text: str) -> Any:
    """The JSON value of one ``impact_cmd`` text (its fields are checked by
    ``Impact.from_mapping``)."""
    if len(text) > MAX_COMMAND_CHARS:
        raise InputError(
            "impact_cmd", text, f"must be at most {MAX_COMMAND_CHARS} characters of JSON"
        )
    if nesting_depth(text) > MAX_NESTING:
        raise InputError(
            "impact_cmd", text, f"must be one flat JSON object (nested {nesting_depth(text)} deep)"
        )
    try:
        return json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise InputError(
            "impact_cmd", text, f"not valid JSON ({exc.msg} at char {exc.pos})"
        ) from None
    except (
        RecursionError,
        ValueError,
    ) as exc:  # belt and braces: the checks above should prevent these
        raise InputError(
            "impact_cmd", text, f"not a JSON object this node can read ({type(exc).__name__})"
        ) from None
