"""maps.export.labels.near_segments: the label placement measures each candidate against the track
segments that can be nearest to it, with the same minimum bit for bit as against all of them."""

from __future__ import annotations

import numpy as np

from maps.export.labels import _ANGLES, near_segments, segment_distances


def test_near_segments_give_the_same_minimum_bit_for_bit():
    rng = np.random.default_rng(7)
    for _ in range(200):
        m = int(rng.integers(1, 400))
        track = np.cumsum(rng.normal(0.0, rng.uniform(1.0, 30.0), (m + 1, 2)), axis=0)
        a, b = track[:-1], track[1:]
        anchor = track[int(rng.integers(0, m + 1))] + rng.normal(0.0, 5.0, 2)
        r = float(rng.uniform(2.0, 12.0))
        rings = [anchor + 7.0] + [
            anchor + (2 * r + 1.5 * k * r) * np.column_stack([np.cos(_ANGLES), np.sin(_ANGLES)]) for k in range(1, 9)
        ]
        cand = np.vstack(rings)
        reach = float(np.hypot(cand[:, 0] - anchor[0], cand[:, 1] - anchor[1]).max())
        near = near_segments(anchor, reach, a, b)
        assert np.array_equal(segment_distances(cand, a[near], b[near]), segment_distances(cand, a, b))


def test_near_segments_leave_out_the_far_ones():
    a = np.array([[0.0, 0.0], [1000.0, 0.0]])
    b = np.array([[10.0, 0.0], [1010.0, 0.0]])
    assert near_segments(np.array([5.0, 1.0]), 50.0, a, b).tolist() == [0]
    assert near_segments(np.array([5.0, 1.0]), 600.0, a, b).tolist() == [0, 1]
    assert near_segments(np.array([5.0, 1.0]), 50.0, a[:0], b[:0]).tolist() == []
