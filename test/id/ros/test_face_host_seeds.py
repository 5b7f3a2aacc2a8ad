"""face_host's seeds per support: a face spread over several hosts draws as one host would."""

from __future__ import annotations

import pytest

from tail_beam_id.ros.face_host import support_index, support_indices
from tail_beam_sim.errors import InputError


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


def test_two_namespaces_that_would_be_one_support_are_refused_by_name():
    """/support_002 and a name in second place would both run support 2's seeds (the same
    impacts): refused, naming face_host.namespaces and both namespaces; numbered ones pass."""
    with pytest.raises(InputError) as refused:
        support_indices(["/support_002", "/left"])
    assert "face_host.namespaces" in str(refused.value)
    assert "/support_002" in str(refused.value) and "/left" in str(refused.value)
    assert support_indices(["/support_004", "/support_005"]) == [3, 4]
    assert support_indices(["/left", "/right"]) == [0, 1]
