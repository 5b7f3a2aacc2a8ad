"""The batch-hashed seed children against numpy's own SeedSequence (the independent reference):
the same PCG64 seed words, so the same generators and draws."""

import numpy as np
import pytest

from tail_beam_sim.physics import seeds

EDGE_SEEDS = [0, 1, 2, 255, 2**31, 2**32 - 1, 2**32, 2**32 + 1, 2**63, 2**64 - 1]


def _random_seeds() -> list[int]:
    rng = np.random.default_rng(20261127)
    small = rng.integers(0, 2**32, 200, dtype=np.uint64)
    large = rng.integers(0, 2**64 - 1, 200, dtype=np.uint64, endpoint=True)
    return [int(s) for s in np.concatenate([small, large])]


@pytest.mark.parametrize("count", [1, 6, 9])
def test_children_give_numpys_seed_words(count):
    """Each child's PCG64 seed words equal numpy's child's, for edge and random seeds."""
    batch = EDGE_SEEDS + _random_seeds()
    for seed, made in zip(batch, seeds.spawn_many(batch, count)):
        reference = np.random.SeedSequence(seed).spawn(count)
        assert len(made) == count
        for mine, theirs in zip(made, reference):
            assert isinstance(mine, seeds.Child)
            assert np.array_equal(
                mine.generate_state(4, np.uint64), theirs.generate_state(4, np.uint64)
            )


def test_generators_draw_what_numpys_draw():
    """Generators made from the children draw numpy's children's generators' numbers."""
    batch = [0, 1, 2**32 - 1, 123456789, 2**64 - 1]
    for seed, made in zip(batch, seeds.spawn_many(batch, 6)):
        for mine, theirs in zip(made, np.random.SeedSequence(seed).spawn(6)):
            ours, reference = seeds.generator(mine), np.random.default_rng(theirs)
            assert np.array_equal(ours.standard_normal(50), reference.standard_normal(50))
            assert ours.random() == reference.random()
            assert np.array_equal(ours.normal(0.0, 0.3, 3), reference.normal(0.0, 0.3, 3))


def test_other_requests_are_numpys_child():
    """Any other generate_state request is answered as numpy's child answers it."""
    (child,) = seeds.spawn_many([77], 1)[0]
    reference = np.random.SeedSequence(77).spawn(1)[0]
    for n_words, dtype in ((1, np.uint32), (3, np.uint32), (8, np.uint64), (2, np.uint64)):
        assert np.array_equal(
            child.generate_state(n_words, dtype), reference.generate_state(n_words, dtype)
        )


def test_numpy_integer_seeds_are_covered():
    """numpy integer seeds are hashed here and give what their int value gives numpy."""
    batch = [np.uint32(5), np.int64(2**40), np.uint64(2**64 - 1)]
    for seed, made in zip(batch, seeds.spawn_many(batch, 3)):
        assert seeds.covered(seed)
        for mine, theirs in zip(made, np.random.SeedSequence(int(seed)).spawn(3)):
            assert np.array_equal(
                mine.generate_state(4, np.uint64), theirs.generate_state(4, np.uint64)
            )


@pytest.mark.parametrize("seed", [2**64, 2**100 + 3, [1, 2, 3], True])
def test_uncovered_seeds_go_through_numpy(seed):
    """Seeds past 2**64, arrays and bools are left to numpy's SeedSequence."""
    assert not seeds.covered(seed)
    (made,) = seeds.spawn_many([seed], 4)
    for mine, theirs in zip(made, np.random.SeedSequence(seed).spawn(4)):
        assert isinstance(mine, np.random.SeedSequence)
        assert np.array_equal(
            mine.generate_state(4, np.uint64), theirs.generate_state(4, np.uint64)
        )


def test_negative_seed_is_refused_as_numpy_refuses_it():
    """A negative seed raises numpy's ValueError."""
    assert not seeds.covered(-1)
    with pytest.raises(ValueError):
        seeds.spawn_many([-1], 6)


def test_kept_children_are_the_same_objects_and_batches_mix():
    """A seed asked again gets the kept objects; a batch of kept and new seeds is right."""
    first = seeds.children([3, 4, 3], 6)
    assert first[0] is first[2]
    again = seeds.children([4, 5], 6)
    assert again[0] is first[1]
    for seed, made in zip([4, 5], again):
        for mine, theirs in zip(made, np.random.SeedSequence(seed).spawn(6)):
            assert seeds.generator(mine).random() == np.random.default_rng(theirs).random()
