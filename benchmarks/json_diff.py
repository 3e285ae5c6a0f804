"""The largest relative difference between the numbers of two JSON documents of the same shape (stop 51: a
change that reorders floating-point sums leaves ``detect --json`` equal to rounding, not byte for byte).

    python benchmarks/json_diff.py before.json after.json

Every field is walked; keys, list lengths, strings, booleans and nulls must be equal (else it says where they
differ, exit 1); for numbers it prints the largest |a - b| / max(|a|, |b|) and whether the files' bytes agree.
"""

from __future__ import annotations

import json
import sys


def largest(a: object, b: object, path: str = "") -> float:
    """Largest relative difference of the numbers of ``a`` and ``b``; ValueError where their shape differs."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            raise ValueError(f"{path or '/'}: keys differ")
        return max([largest(a[k], b[k], f"{path}/{k}") for k in a], default=0.0)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            raise ValueError(f"{path}: lengths {len(a)} and {len(b)}")
        return max([largest(x, y, f"{path}[{i}]") for i, (x, y) in enumerate(zip(a, b))], default=0.0)
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        return 0.0 if a == b else abs(a - b) / max(abs(a), abs(b))
    if a != b:
        raise ValueError(f"{path}: {a!r} and {b!r}")
    return 0.0


def main() -> int:
    first, second = sys.argv[1:3]
    texts = [open(p, encoding="utf-8").read() for p in (first, second)]
    try:
        d = largest(json.loads(texts[0]), json.loads(texts[1]))
    except ValueError as e:
        print(f"{second}: differs from {first} at {e}")
        return 1
    same = "byte-identical" if texts[0] == texts[1] else "bytes differ"
    print(f"largest relative difference {d:.3g} ({same})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
