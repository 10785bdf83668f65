"""Random streams derived from (base seed, what, wildcards): never from what ran before.

A run's stream depends only on its own keys, so results do not depend on job order or ``-j``.
String keys (algorithm names) enter through a stable CRC32, not Python's salted ``hash``.
"""

from __future__ import annotations

import zlib

import numpy as np


def _key(k) -> int:
    if isinstance(k, str):
        return zlib.crc32(k.encode())
    return int(k)


def stream(base_seed: int, *keys) -> np.random.Generator:
    return np.random.Generator(
        np.random.PCG64(np.random.SeedSequence([base_seed, *map(_key, keys)]))
    )
