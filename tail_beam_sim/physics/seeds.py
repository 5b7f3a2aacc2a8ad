"""numpy's ``SeedSequence(seed).spawn(count)`` children for many seeds at once.

A sensor suite draws each sensor's noise from its own child of the scene's seed. numpy builds a
child one Python-level hash at a time and hashes again for every generator made from it, which
costs more than the few hundred normal draws of an impact's streams. The children's hashing is
uint32 arithmetic with the same constants for every seed, so here it runs as array operations
over every (seed, child) pair of a batch: numpy's ``SeedSequence`` algorithm (``mix_entropy``
over the run entropy padded to the pool and the spawn key, then ``generate_state``), giving
each child's PCG64 seed words. :class:`Child` hands them to ``np.random.PCG64``, which takes
any :class:`numpy.random.bit_generator.ISeedSequence`: the generators are bit-identical to
``np.random.default_rng(SeedSequence(seed).spawn(count)[k])``.

Seeds covered: integers 0 <= seed < 2**64 (a sensor seed is one uint32 or uint64 word); any
other seed goes through numpy's own ``SeedSequence``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.random.bit_generator import ISeedSequence

POOL_SIZE = 4  # numpy's DEFAULT_POOL_SIZE
INIT_A = 0x43B0D7E5
MULT_A = 0x931E8875
INIT_B = 0x8B51F9DD
MULT_B = 0x58F38DED
MIX_MULT_L = 0xCA01F9DD
MIX_MULT_R = 0x4973F715
MASK32 = 0xFFFFFFFF
COVERED_LIMIT = 2**64  # seeds below it (and >= 0) are hashed here


class Child(ISeedSequence):
    """A spawned child of ``SeedSequence(entropy)`` (spawn key ``(index,)``) whose PCG64 seed
    words (``generate_state(4, np.uint64)``) are already computed; any other request is
    answered by numpy's own child."""

    __slots__ = ("entropy", "index", "_words")

    def __init__(self, entropy: int, index: int, words: np.ndarray) -> None:
        self.entropy = entropy
        self.index = index
        self._words = words

    def generate_state(self, n_words: int, dtype: Any = np.uint32) -> np.ndarray:
        if n_words == 4 and (dtype is np.uint64 or np.dtype(dtype) == np.uint64):
            return self._words
        return self.sequence().generate_state(n_words, dtype)

    def sequence(self) -> np.random.SeedSequence:
        """numpy's own child this stands for."""
        return np.random.SeedSequence(self.entropy, spawn_key=(self.index,))

    def generator(self) -> np.random.Generator:
        """``np.random.default_rng(child)``: a PCG64 generator."""
        return np.random.Generator(np.random.PCG64(self))


def covered(seed: object) -> bool:
    """Whether :func:`spawn_many` hashes ``seed`` itself (else numpy does)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        return False
    return 0 <= int(seed) < COVERED_LIMIT


def _hash_constants(start: int, multiplier: int, count: int) -> list[int]:
    """The running hash constant numpy's hashing multiplies through, one per use."""
    out, value = [], start
    for _ in range(count):
        out.append(value)
        value = (value * multiplier) & MASK32
    return out


# mix_entropy over five words (a padded run entropy of four and a one-word spawn key):
# four hashes of the entropy, twelve cross-mixes, four of the spawn key
_MIX_HASHES = _hash_constants(INIT_A, MULT_A, POOL_SIZE + POOL_SIZE * (POOL_SIZE - 1) + POOL_SIZE)
_STATE_HASHES = _hash_constants(INIT_B, MULT_B, 8)


def _hashmix(value: np.ndarray, step: int) -> np.ndarray:
    """numpy's hashmix at its ``step``-th use of the running constant (uint32 arrays)."""
    value = value ^ _MIX_XOR[step]
    value = value * _MIX_MUL[step]
    return value ^ (value >> _SHIFT)


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    result = _MIX_L * x - _MIX_R * y
    return result ^ (result >> _SHIFT)


_SHIFT = np.uint32(16)
_MIX_L, _MIX_R = np.uint32(MIX_MULT_L), np.uint32(MIX_MULT_R)
_MIX_XOR = [np.uint32(c) for c in _MIX_HASHES]
_MIX_MUL = [np.uint32((c * MULT_A) & MASK32) for c in _MIX_HASHES]


def _pcg_words(seeds: np.ndarray, count: int) -> np.ndarray:
    """(S, count, 4) uint64: ``SeedSequence(seed).spawn(count)[k].generate_state(4, uint64)``
    for uint64 ``seeds`` (S,).

    A child's entropy is the seed's words padded with zeros to the pool (numpy pads a spawned
    sequence's run entropy), then its spawn key: the pool's first two mixing rounds depend on
    the seed alone, the spawn key's hashes on the child alone."""
    low = (seeds & np.uint64(MASK32)).astype(np.uint32)
    high = (seeds >> np.uint64(32)).astype(np.uint32)  # 0 below 2**32: numpy's padding zero
    zero = np.zeros(seeds.size, dtype=np.uint32)
    entropy = [low, high, zero, zero]
    pool = [_hashmix(entropy[i], i) for i in range(POOL_SIZE)]
    step = POOL_SIZE
    for src in range(POOL_SIZE):
        for dst in range(POOL_SIZE):
            if src != dst:
                pool[dst] = _mix(pool[dst], _hashmix(pool[src], step))
                step += 1
    key = np.arange(count, dtype=np.uint32)
    mixed = [
        _mix(pool[dst][:, None], _hashmix(key, step + dst)[None, :]) for dst in range(POOL_SIZE)
    ]  # (S, count) each
    state = np.empty((seeds.size, count, 2 * POOL_SIZE), dtype=np.uint32)
    for i, constant in enumerate(_STATE_HASHES):
        value = mixed[i % POOL_SIZE] ^ np.uint32(constant)
        value = value * np.uint32((constant * MULT_B) & MASK32)
        state[:, :, i] = value ^ (value >> _SHIFT)
    words = state.astype(np.uint64)  # little-endian pairs of uint32, as numpy views them
    return words[..., 0::2] | (words[..., 1::2] << np.uint64(32))


def spawn_many(seeds: Sequence[object], count: int) -> list[tuple[Any, ...]]:
    """For each seed, its ``count`` children as ``np.random.SeedSequence(seed).spawn(count)``
    gives them: :class:`Child` for covered seeds (:func:`covered`), numpy's own otherwise. Each
    child's generator: :func:`generator`."""
    mine = [k for k, seed in enumerate(seeds) if covered(seed)]
    out: list[tuple[Any, ...]] = [()] * len(seeds)
    if mine:
        values = [int(seeds[k]) for k in mine]  # type: ignore[call-overload]
        words = _pcg_words(np.array(values, dtype=np.uint64), count)
        words.flags.writeable = False  # each child hands out its row: read, never written
        for row, (k, seed) in enumerate(zip(mine, values)):
            out[k] = tuple(Child(seed, i, words[row, i]) for i in range(count))
    for k, seed in enumerate(seeds):
        if not covered(seed):
            out[k] = tuple(np.random.SeedSequence(seed).spawn(count))  # type: ignore[arg-type]
    return out


_KEPT: dict[tuple[Any, int], tuple[Any, ...]] = {}
KEPT_SEEDS = 1024  # children kept, per (seed, count), beyond the last batch's


def children(seeds: Sequence[Any], count: int) -> list[tuple[Any, ...]]:
    """:func:`spawn_many`, each seed's children kept: a seed asked again gets the same objects
    (a child is only read, never spawned from). The seeds missing are hashed in one batch;
    the kept set is emptied when it would pass KEPT_SEEDS, never of the batch's own."""
    missing = list({seed: None for seed in seeds if (seed, count) not in _KEPT})
    if missing:
        if len(_KEPT) + len(missing) > KEPT_SEEDS:
            _KEPT.clear()
        for seed, made in zip(missing, spawn_many(missing, count)):
            _KEPT[(seed, count)] = made
    return [_KEPT[(seed, count)] for seed in seeds]


def children_of(seed: Any, count: int) -> tuple[Any, ...]:
    """:func:`children` of one seed."""
    kept = _KEPT.get((seed, count))
    return kept if kept is not None else children([seed], count)[0]


def generator(child: Any) -> np.random.Generator:
    """``np.random.default_rng(child)`` of a child :func:`spawn_many` gave."""
    if isinstance(child, Child):
        return child.generator()
    return np.random.default_rng(child)
