#!/usr/bin/env bash
# Peer benchmark, same mesh, same run: NVIDIA Warp `eval_tetrahedra` (CPU) vs `heml bench`.
# Benchmark-only; nothing here is used by `cargo test`. See bench/peers/README.md.
#
# usage: bench/peers/run.sh [MESH.msh]
# env:   WARP_PY   python with warp-lang==1.9.1 + numpy (default /tmp/warpvenv/bin/python;
#                  created with `python3 -m venv /tmp/warpvenv && /tmp/warpvenv/bin/pip install warp-lang==1.9.1 numpy`)
#        HEML      heml binary (default <repo>/target/release/heml; build with `cargo build --release`)
#        REPEATS   timed samples per measurement (default 25)
#        PIN       e.g. "taskset -c 1" to pin every process (default: no pinning)
#        RAPIER    1 (default) to also build and time the rapier3d soft-body step (bench/peers/rapier,
#                  a standalone package, target dir $RAPIER_TARGET, default /tmp/heml-peers-rapier-target); 0 to skip
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
mesh="${1:-/work/shared/meshes/msh/gen_kidney_100k.msh}"
py="${WARP_PY:-/tmp/warpvenv/bin/python}"
heml="${HEML:-$repo/target/release/heml}"
repeats="${REPEATS:-25}"
pin="${PIN:-}"

[ -x "$heml" ] || { echo "no heml binary at $heml (cargo build --release)" >&2; exit 1; }
"$py" -c 'import warp, numpy' 2>/dev/null || { echo "$py lacks warp-lang/numpy (see header)" >&2; exit 1; }

echo "== $(date -u +%FT%TZ)  $(uname -m)  $(nproc) cpus  $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "== load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== mesh: $mesh"

echo; echo "== Warp $("$py" -c 'import warp; print(warp.__version__)') eval_tetrahedra, device cpu (single-threaded, float32)"
warp_out="$($pin "$py" "$here/warp_tet_forces.py" --mesh "$mesh" --repeats "$repeats" 2>&1 | grep -v -e DeprecationWarning -e 'CUDA driver')"
echo "$warp_out"
warp_s="$(echo "$warp_out" | sed -n 's/.*WARP_RESULT .* median_s=\([^ ]*\).*/\1/p')"
warp_zs="$(echo "$warp_out" | sed -n 's/.*median_zero_s=\([^ ]*\).*/\1/p')"
tets="$(echo "$warp_out" | sed -n 's/.*WARP_RESULT tets=\([0-9]*\).*/\1/p')"

echo; echo "== HEML neo_hookean, --threads 1 (float64)"
h1_out="$($pin "$heml" bench --mesh "$mesh" --law neo_hookean --threads 1 --repeats "$repeats")"
echo "$h1_out"
echo; echo "== HEML neo_hookean, --threads 2 (float64)"
h2_out="$($pin "$heml" bench --mesh "$mesh" --law neo_hookean --threads 2 --repeats "$repeats")"
echo "$h2_out"
# table row: threads  HEML tets/s  ns/tet  P1 tets/s  ns/tet  ratio
h1="$(echo "$h1_out" | awk '$1=="1" && NF>=6 {print $2; exit}')"
h2="$(echo "$h2_out" | awk '$1=="2" && NF>=6 {print $2; exit}')"
p1="$(echo "$h1_out" | awk '$1=="1" && NF>=6 {print $4; exit}')"

rapier_c=""; rapier_f=""
if [ "${RAPIER:-1}" = 1 ]; then
  rt="${RAPIER_TARGET:-/tmp/heml-peers-rapier-target}"
  echo; echo "== rapier3d 0.36.1 soft-body step (features fem; single thread, f32; full step, not a force evaluation)"
  CARGO_TARGET_DIR="$rt" cargo build --quiet --release --manifest-path "$here/rapier/Cargo.toml"
  r_out="$($pin "$rt/release/heml-peer-rapier" "$mesh" "$repeats" constraints)"; echo "$r_out"
  rapier_c="$(echo "$r_out" | sed -n 's/.*RAPIER_RESULT .* median_s=\([^ ]*\).*/\1/p')"
  r_out="$($pin "$rt/release/heml-peer-rapier" "$mesh" 7 fem)"; echo "$r_out"
  rapier_f="$(echo "$r_out" | sed -n 's/.*RAPIER_RESULT .* median_s=\([^ ]*\).*/\1/p')"
fi
hs1="$(echo "$h1_out" | sed -n 's/^full step.*: \([0-9.]*\) ms median.*/\1/p')"
hs2="$(echo "$h2_out" | sed -n 's/^full step.*: \([0-9.]*\) ms median.*/\1/p')"

echo; echo "== load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$tets" "$warp_s" "$warp_zs" "$h1" "$h2" "$p1" "$hs1" "$hs2" "${rapier_c:-nan}" "${rapier_f:-nan}" <<'PY'
import sys, math
n, ws, wzs, h1, h2, p1, hs1, hs2, rc, rf = int(sys.argv[1]), *map(float, sys.argv[2:])
w = n / ws
wz = n / wzs
print(f"\n== summary ({n} tets, medians)")
print(f"Warp CPU eval_tetrahedra (1 thread, f32): {ws*1e3:.3f} ms/eval, {w/1e6:.2f} M tets/s, {1e9/w:.1f} ns/tet"
      f"  (with f.zero_(): {wzs*1e3:.3f} ms, {wz/1e6:.2f} M tets/s)")
print(f"HEML neo_hookean 1 thread (f64):         {n/h1*1e3:.3f} ms/eval, {h1/1e6:.2f} M tets/s, {1e9/h1:.1f} ns/tet")
print(f"HEML neo_hookean 2 threads (f64):        {n/h2*1e3:.3f} ms/eval, {h2/1e6:.2f} M tets/s, {1e9/h2:.1f} ns/tet")
print(f"HEML in-repo P1 path 1 thread (f64):     {p1/1e6:.2f} M tets/s")
print(f"ratio HEML 1 thread / Warp CPU:  {h1/w:.2f}x")
print(f"ratio HEML 2 threads / Warp CPU: {h2/w:.2f}x")
print(f"HEML full semi-explicit step: {hs1:.3f} ms (1 thread), {hs2:.3f} ms (2 threads)")
if not math.isnan(rc):
    print(f"rapier3d step, Constraints solver: {rc*1e3:.1f} ms; Fem solver: {rf*1e3:.1f} ms (dt 1/60, 4 substeps, 1 thread)")
    print(f"step-time ratio rapier/HEML (1 thread, NOT like for like: implicit/constraint step vs explicit step): "
          f"{rc*1e3/hs1:.0f}x (Constraints), {rf*1e3/hs1:.0f}x (Fem)")
PY
