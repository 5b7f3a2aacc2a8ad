"""face_host's seeds per support: a face spread over several hosts draws as one host would."""

from __future__ import annotations

import pytest

from tail_beam_id.ros.face_host import support_index


@pytest.mark.parametrize(
    "namespace, position, index",
    [
        ("/support_001", 0, 0),
        ("/support_004", 0, 3),  # the first of a second host's list is still the fourth support
        ("/support_150/", 1, 149),
        ("/face_a/support_012", 5, 11),
    ],
)
def test_a_numbered_namespace_sets_the_support_it_is(namespace, position, index):
    """``/support_NNN`` is support NNN - 1 (its seeds base + (NNN - 1) x stride), whatever its
    place in this host's list: two hosts running /support_001-002 and /support_003-004 draw
    what one host running all four draws."""
    assert support_index(namespace, position) == index


@pytest.mark.parametrize("namespace", ["/left", "/support_000", "/support_x", "/supports_7x"])
def test_another_namespace_takes_its_place_in_the_list(namespace):
    """A namespace that numbers no support (or numbers it 0) is counted by its place."""
    assert support_index(namespace, 2) == 2
