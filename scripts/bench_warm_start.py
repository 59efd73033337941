#!/usr/bin/env python
"""Benchmark: does a warm start pay in a robustness study? A resampled mesh's spectrum solved from
a random start block, and from random combinations of its reference's eigenvectors transferred onto
it (``interpolation.transfer``), measured in one run on the same factor.

    .venv/bin/python scripts/bench_warm_start.py            # the 20k-vertex bunny, k = 100
    .venv/bin/python scripts/bench_warm_start.py --n 50000

Prints a Markdown table: solves and seconds of the block Lanczos for each start, and the seconds
the transfer of the k reference eigenvectors costs (the warm start pays only when the time it
saves exceeds that).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_spectrum import bunny  # noqa: E402

import o3dheat  # noqa: E402
from o3dheat.geometry import interpolation, sampling  # noqa: E402
from o3dheat.spectral import _solvers, fem, lanczos, linalg

RESAMPLINGS = [("jitter", {"amount": 0.3}), ("decimate", {"reduction": 0.5}), ("remesh", {}), ("anisotropic", {})]


def best(fn, repeat):
    out, t = None, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        t = min(t, time.perf_counter() - t0)
    return out, t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=20000)
    ap.add_argument("--k", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    V, F = bunny(args.n)
    ref = o3dheat.eigensolve((V, F), k=args.k)
    print("| resampling | n | random start: solves, s | warm start: solves, s | transfer s | net saving s |")
    print("|---|---|---|---|---|---|")
    for kind, params in RESAMPLINGS:
        r = sampling.resample((V, F), kind, **params)
        X0, t_transfer = best(lambda: interpolation.transfer(ref.eigenvectors, (V, F), r.V), args.repeat)  # noqa: B023 - best calls it at once
        L, B, _ = fem.operators(r.V, r.F, "consistent")
        perm = reverse_cuthill_mckee(sp.csr_matrix(L), symmetric_mode=True)
        L, B = _solvers._permuted(L, perm), _solvers._permuted(B, perm)
        s = _solvers._shift(B)
        fac = linalg.factorize(L - s * B)
        start = X0[perm] @ np.random.default_rng(1).standard_normal((args.k, 8))
        cold, t_cold = best(lambda: lanczos.block_lanczos(L, B, fac.solve, args.k, s), args.repeat)  # noqa: B023 - best calls it at once
        warm, t_warm = best(lambda: lanczos.block_lanczos(L, B, fac.solve, args.k, s, start=start), args.repeat)  # noqa: B023 - best calls it at once
        assert np.allclose(cold[0], warm[0], rtol=1e-9, atol=1e-12)
        print(f"| {kind} | {len(r.V)} | {cold[2]['solves']}, {t_cold:.3f} | {warm[2]['solves']}, {t_warm:.3f} | "
              f"{t_transfer:.3f} | {t_cold - t_warm - t_transfer:+.3f} |", flush=True)


if __name__ == "__main__":
    main()
