"""The generators of a chunk's Monte Carlo runs, ``default_rng(SeedSequence(seed, spawn_key=(run,
stream)))`` for each run, made for all the runs at once. The hash is O'Neill's seed_seq_fe, as numpy's
SeedSequence implements it: the pool mixed from the entropy, then the words drawn from the pool. Here it
runs in uint32 arrays over the runs, and gives the four uint64 words that PCG64 seeds itself with. The
generators, and so their draws, are the same (tests/test_runseeds.py checks the words and states against
numpy's for seeds of one to seven 32-bit words).

Why: a 2,000 x 2 Monte Carlo makes 6,000 generators, all while holding the GIL that the chunks'
threads share (:mod:`primitives.threads`). Measured inside that run (one thread, ``time.thread_time``
around the chunk's generator calls, 3 alternated pairs, load 2-3, stop 44 review): numpy's objects
0.15-0.21 s (25-35 us a generator), these 0.034-0.046 s (6-8 us): 0.12-0.17 s of the run's ~7 s CPU
(about 2 %). Outside a run (timeit, 250 runs, min of 7): 19 against 3.5 us.

The generators' ``seed_seq`` is the words, not a SeedSequence, so ``Generator.spawn`` refuses them
(TypeError); nothing in the Monte Carlo spawns from a run's generator.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

# numpy.random.bit_generator's constants (SeedSequence, pool of 4 words of 32 bits)
POOL_SIZE = 4
INIT_A, MULT_A = 0x43B0D7E5, 0x931E8875
INIT_B, MULT_B = 0x8B51F9DD, 0x58F38DED
MIX_MULT_L, MIX_MULT_R = 0xCA01F9DD, 0x4973F715
XSHIFT, MASK32 = 16, 0xFFFFFFFF


class _Words:
    """A seed sequence that hands PCG64 the words it has (numpy's ISeedSequence interface)."""

    __slots__ = ("words",)

    def __init__(self, words: np.ndarray):
        self.words = words

    def generate_state(self, n_words: int, dtype=np.uint32) -> np.ndarray:
        if n_words != len(self.words) or np.dtype(dtype) != np.uint64:  # PCG64 asks for 4 uint64 words
            raise ValueError("these words seed PCG64 only")
        return self.words


np.random.bit_generator.ISeedSequence.register(_Words)


def _uint32_words(n: int) -> list[int]:
    """numpy's coercion of a non-negative integer to 32-bit words, least significant first ([0] for 0)."""
    if n < 0:
        raise ValueError(f"a seed must be non-negative, got {n}")
    words = [n & MASK32]
    n >>= 32
    while n:
        words.append(n & MASK32)
        n >>= 32
    return words


def _entropy(seed: int, runs: np.ndarray, stream: int) -> list[np.ndarray]:
    """SeedSequence(seed, spawn_key=(run, stream))'s assembled entropy for every run (each word a
    (B,) uint32 array): the seed's words, zero-padded to the pool (a spawn key follows), then the
    run's word and the stream's words."""
    seed_words = _uint32_words(seed)
    words = seed_words + [0] * (POOL_SIZE - len(seed_words)) + [None] + _uint32_words(stream)
    return [runs.astype(np.uint32) if w is None else np.full(len(runs), w, np.uint32) for w in words]


def _pools(entropy: list[np.ndarray]) -> list[np.ndarray]:
    """SeedSequence's pool (4 words, each (B,)) from its entropy: numpy's mix_entropy (hashmix and
    mix in uint32 arithmetic, which wraps as C's does), for all runs at once."""
    h = INIT_A

    def hashmix(value: np.ndarray) -> np.ndarray:
        nonlocal h
        value = value ^ np.uint32(h)
        h = (h * MULT_A) & MASK32
        value = value * np.uint32(h)
        return value ^ (value >> np.uint32(XSHIFT))

    def mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        r = np.uint32(MIX_MULT_L) * x - np.uint32(MIX_MULT_R) * y
        return r ^ (r >> np.uint32(XSHIFT))

    mixer = [hashmix(entropy[i]) for i in range(POOL_SIZE)]  # the entropy has at least POOL_SIZE words
    for src in range(POOL_SIZE):
        for dst in range(POOL_SIZE):
            if src != dst:
                mixer[dst] = mix(mixer[dst], hashmix(mixer[src]))
    for value in entropy[POOL_SIZE:]:
        for dst in range(POOL_SIZE):
            mixer[dst] = mix(mixer[dst], hashmix(value))
    return mixer


def state_words(seed: int, runs: np.ndarray, stream: int, n_words: int = 4) -> np.ndarray:
    """SeedSequence(seed, spawn_key=(run, stream)).generate_state(n_words, np.uint64) of every run
    (len(runs), n_words)."""
    mixer, h = _pools(_entropy(seed, runs, stream)), INIT_B
    out = np.empty((len(runs), 2 * n_words), np.uint32)
    for i in range(2 * n_words):
        v = mixer[i % POOL_SIZE] ^ np.uint32(h)
        h = (h * MULT_B) & MASK32
        v = v * np.uint32(h)
        out[:, i] = v ^ (v >> np.uint32(XSHIFT))
    # 32-bit words paired little-endian into 64-bit ones, as numpy does on every platform
    return out.astype("<u4").view("<u8").astype(np.uint64)


def run_rngs(seed: int, runs: Sequence[int], stream: int) -> list[np.random.Generator]:
    """``[np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, stream))) for run in
    runs]``: the same generators in the same states (numpy's own where a run index or the stream
    does not fit one 32-bit word)."""
    runs = np.asarray(runs, np.int64).reshape(-1)
    if not runs.size:
        return []
    if runs.min() < 0 or runs.max() > MASK32 or not 0 <= stream <= MASK32 or seed < 0:
        return [np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(r), stream))) for r in runs]
    return [np.random.Generator(np.random.PCG64(_Words(w))) for w in state_words(int(seed), runs, int(stream))]
