#!/usr/bin/env python3
"""Time NVIDIA Warp's tetrahedral FEM force kernel (warp.sim `eval_tetrahedra`) on CPU.

Benchmark-only peer comparison for HEML (issue 5). Not used by `cargo test`.
Requires `warp-lang==1.9.1` (the last release that ships `warp.sim`) and numpy:

    python3 -m venv /tmp/warpvenv && /tmp/warpvenv/bin/pip install warp-lang==1.9.1 numpy
    /tmp/warpvenv/bin/python bench/peers/warp_tet_forces.py --mesh MESH.msh

Reads a Gmsh 4.1 ASCII .msh (4-node tets, element type 4) with a small parser of its own.
Builds a warp.sim soft mesh (ModelBuilder.add_soft_mesh, k_damp = 0) on device "cpu",
stretches the state slightly, records one launch of `eval_tetrahedra`
(wp.launch(..., record_cmd=True)) and replays it; prints the median time per evaluation.
Warp's CPU backend runs a kernel launch serially on one thread, and in float32.
"""
import argparse
import os
import statistics
import sys
import time

import numpy as np


def read_msh41(path):
    """Return (points [N,3] float64, tets [M,4] int, 0-based) from a Gmsh 4.1 ASCII file."""
    with open(path, "r") as fh:
        lines = fh.read().split("\n")
    i = 0
    fmt = None
    tag_to_idx = {}
    pts = []
    tets = []
    n = len(lines)
    while i < n:
        s = lines[i].strip()
        if s == "$MeshFormat":
            fmt = lines[i + 1].split()
            if not fmt[0].startswith("4.1") or fmt[1] != "0":
                sys.exit(f"{path}: only Gmsh 4.1 ASCII is supported (found {' '.join(fmt)})")
            i += 2
        elif s == "$Nodes":
            nblocks, _nnodes, _mn, _mx = map(int, lines[i + 1].split())
            i += 2
            for _ in range(nblocks):
                _dim, _tag, parametric, nb = map(int, lines[i].split())
                i += 1
                tags = [int(lines[i + k]) for k in range(nb)]
                i += nb
                for k in range(nb):
                    c = lines[i + k].split()
                    tag_to_idx[tags[k]] = len(pts)
                    pts.append((float(c[0]), float(c[1]), float(c[2])))
                i += nb
        elif s == "$Elements":
            nblocks, _nel, _mn, _mx = map(int, lines[i + 1].split())
            i += 2
            for _ in range(nblocks):
                _dim, _tag, etype, nb = map(int, lines[i].split())
                i += 1
                if etype == 4:
                    for k in range(nb):
                        c = lines[i + k].split()
                        tets.append(tuple(tag_to_idx[int(t)] for t in c[1:5]))
                i += nb
        else:
            i += 1
    if fmt is None or not tets:
        sys.exit(f"{path}: no $MeshFormat or no 4-node tetrahedra")
    return np.asarray(pts, dtype=np.float64), np.asarray(tets, dtype=np.int64)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh", required=True)
    ap.add_argument("--repeats", type=int, default=25, help="timed samples (median reported)")
    ap.add_argument("--inner", type=int, default=10, help="evaluations per timed sample")
    ap.add_argument("--mu", type=float, default=3.4e4, help="k_mu (Pa)")
    ap.add_argument("--lam", type=float, default=1.6e5, help="k_lambda (Pa)")
    args = ap.parse_args()

    import warp as wp

    wp.config.quiet = True
    wp.config.kernel_cache_dir = os.environ.get("WARP_CACHE_PATH", "/tmp/warp-kernel-cache")
    wp.init()
    import warp.sim
    from warp.sim.integrator_euler import eval_tetrahedra

    t0 = time.perf_counter()
    pts, tets = read_msh41(args.mesh)
    # Warp's add_tetrahedron drops elements with non-positive rest volume:
    # orient every tet positively so that all of them are kept (same tets as HEML).
    p = pts[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    print(f"mesh: {args.mesh}: {len(pts)} nodes, {len(tets)} tets ({int(neg.sum())} reoriented), "
          f"read in {time.perf_counter() - t0:.2f} s")

    t0 = time.perf_counter()
    builder = wp.sim.ModelBuilder()
    builder.add_soft_mesh(
        pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
        vertices=pts.tolist(), indices=tets.reshape(-1).tolist(), density=1000.0,
        k_mu=args.mu, k_lambda=args.lam, k_damp=0.0,
    )
    model = builder.finalize(device="cpu")
    state = model.state()
    control = model.control()
    assert model.tet_count == len(tets), (model.tet_count, len(tets))
    print(f"warp.sim model: {model.particle_count} particles, {model.tet_count} tets, "
          f"built in {time.perf_counter() - t0:.2f} s")

    # deform slightly: 1 % stretch in x plus small noise (all tets stay positive)
    rng = np.random.default_rng(1)
    q = pts.astype(np.float64).copy()
    ext = q.max(0) - q.min(0)
    q[:, 0] *= 1.01
    q += rng.normal(scale=1e-4 * ext.max(), size=q.shape)
    state.particle_q.assign(q.astype(np.float32))
    f = wp.zeros(model.particle_count, dtype=wp.vec3, device="cpu")

    inputs = [state.particle_q, state.particle_qd, model.tet_indices, model.tet_poses,
              control.tet_activations, model.tet_materials]
    # warm-up (JIT compile + load the CPU module), then record one launch
    t0 = time.perf_counter()
    wp.launch(eval_tetrahedra, dim=model.tet_count, inputs=inputs, outputs=[f], device="cpu")
    wp.synchronize()
    print(f"warm-up (compile/load) {time.perf_counter() - t0:.2f} s")
    cmd = wp.launch(eval_tetrahedra, dim=model.tet_count, inputs=inputs, outputs=[f], device="cpu",
                    record_cmd=True)
    fsum = f.numpy().astype(np.float64)
    print(f"check: |sum f| / sum|f| = {np.linalg.norm(fsum.sum(0)) / np.abs(fsum).sum():.2e} "
          f"(float32 round-off expected), finite: {bool(np.isfinite(fsum).all())}")
    for _ in range(3):
        cmd.launch()

    def sample(zero):
        t = time.perf_counter()
        for _ in range(args.inner):
            if zero:
                f.zero_()
            cmd.launch()
        wp.synchronize()
        return (time.perf_counter() - t) / args.inner

    # interleave the two variants so that load drifts hit both alike
    samples = {False: [], True: []}
    for _ in range(args.repeats):
        for zero in (False, True):
            samples[zero].append(sample(zero))
    res = {zero: statistics.median(v) for zero, v in samples.items()}
    n = model.tet_count
    for zero, label in ((False, "eval_tetrahedra (recorded launch)"),
                        (True, "f.zero_() + eval_tetrahedra")):
        m = res[zero]
        print(f"warp {label}: median {m * 1e3:.3f} ms/eval, {n / m / 1e6:.2f} M tets/s, "
              f"{m / n * 1e9:.1f} ns/tet")
    # machine-readable line for run.sh
    print(f"WARP_RESULT tets={n} median_s={res[False]:.9e} median_zero_s={res[True]:.9e}")


if __name__ == "__main__":
    main()
