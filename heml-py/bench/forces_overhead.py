"""Overhead of a Python call to ForceField.forces against the same evaluation timed
inside Rust, on generated boxes of about 1k, 100k and 1M tets, and of a Python-driven
stepping loop (one `step` call per step) against the Rust loop (`step(n=N)`).

    python heml-py/bench/forces_overhead.py [--quick]

Calls are interleaved (one Python call, one Rust call, per round, in alternating
order) so that the machine's drifts and cache warmth hit both sides alike; medians
of the per-round ratios are quoted. Run it once (it is not a
test: speed is never asserted)."""

import statistics
import sys
import time

import numpy as np

import heml
from heml._heml import _time_forces

QUICK = "--quick" in sys.argv
CASES = [((8, 5, 4), 400), ((48, 24, 15), 40), ((100, 50, 34), 8)]  # 6 tets per cell


def forces_overhead(cells, rounds):
    mesh = heml.box_mesh([c * 0.01 for c in cells], cells)
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    rng = np.random.default_rng(0)
    x = mesh.nodes + 1e-4 * rng.standard_normal(mesh.nodes.shape)
    field.forces(x)  # warm-up: page in the field's data, start the thread pool
    _time_forces(field, x, 1)
    py, rs = [], []
    for k in range(rounds):
        # odd rounds time Rust first: whichever call comes second finds warmer caches
        if k % 2:
            rs.extend(_time_forces(field, x, 1))
        t0 = time.perf_counter()
        field.forces(x)
        py.append(time.perf_counter() - t0)
        if not k % 2:
            rs.extend(_time_forces(field, x, 1))
    mp, mr = statistics.median(py), statistics.median(rs)
    ratios = statistics.median(p / r for p, r in zip(py, rs))
    print(f"{mesh.n_tets:>9} tets: Python call {mp * 1e3:8.3f} ms, Rust call {mr * 1e3:8.3f} ms, "
          f"overhead {mp - mr:+.2e} s = {100 * (ratios - 1):+.1f} % (median of {rounds} paired rounds)")


def stepping_overhead(cells, n):
    mesh = heml.box_mesh([c * 0.01 for c in cells], cells)
    law = heml.material("neo_hookean", E=3e4, nu=0.45)
    make = lambda: heml.System(mesh, law, gravity=[0, 0, -9.81], fixed=mesh.nodes[:, 0] == 0)  # noqa: E731
    a, b = make(), make()
    a.step("symplectic_euler", n=5)
    b.step("symplectic_euler", n=5)
    py, rs = [], []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            a.step("symplectic_euler")
        py.append((time.perf_counter() - t0) / n)
        t0 = time.perf_counter()
        b.step("symplectic_euler", n=n)
        rs.append((time.perf_counter() - t0) / n)
    mp, mr = statistics.median(py), statistics.median(rs)
    print(f"{mesh.n_tets:>9} tets: Python loop {mp * 1e3:.3f} ms/step, Rust loop {mr * 1e3:.3f} ms/step "
          f"({100 * (mp / mr - 1):+.1f} %, median of 5 rounds of {n} steps)")


if __name__ == "__main__":
    print("forces: Python call vs Rust call")
    for cells, rounds in CASES[:2] if QUICK else CASES:
        forces_overhead(cells, rounds)
    print("stepping: one step() call per step vs step(n=N)")
    stepping_overhead((48, 24, 15), 50)
