#!/usr/bin/env bash
# Dependency and packaging checks of the published crates (run by .ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

# 1. `heml` (the library) must not pull in the command's or the validation's crates.
tree=$(cargo tree --locked -p heml -e normal --prefix none)
if echo "$tree" | grep -E '^(plotters|clap|indicatif|core_affinity|criterion|heml-validation|heml-cli|axum|tokio|hyper|fantoccini) ' ; then
  echo "error: the heml library depends on an application crate (above)" >&2
  exit 1
fi
echo "heml's normal dependencies: $(echo "$tree" | sort -u | wc -l) crates, no application crate"

# 2. rust-version: no dependency of a published crate may need a newer compiler than
#    the workspace's rust-version promises.
cargo metadata --locked --format-version 1 | python3 -c '
import json, sys
m = json.load(sys.stdin)
def v(s): return tuple(int(x) for x in s.split("."))[:3] + (0,) * (3 - len(s.split(".")))
ours = {p["name"]: p["rust_version"] for p in m["packages"] if p["source"] is None}
msrv = ours["heml"]
assert msrv, "the heml crate has no rust-version"
for name, rv in ours.items():
    assert rv == msrv, f"{name}: rust-version {rv} differs from the workspace ({msrv})"
by_id = {p["id"]: p for p in m["packages"]}
normal = {}
for node in m["resolve"]["nodes"]:
    normal[node["id"]] = [d["pkg"] for d in node["deps"]
                          if any(k["kind"] in (None, "build") for k in d["dep_kinds"])]
roots = [p["id"] for p in m["packages"] if p["name"] in ("heml", "heml-core", "heml-derive", "heml-symbolic", "heml-materials", "heml-integrators") and p["source"] is None]
seen, todo = set(), list(roots)
while todo:
    i = todo.pop()
    if i in seen: continue
    seen.add(i); todo.extend(normal.get(i, []))
worst = max(((by_id[i]["rust_version"] or "0"), by_id[i]["name"]) for i in seen if by_id[i]["source"])
bad = [(by_id[i]["name"], by_id[i]["rust_version"]) for i in seen
       if by_id[i]["source"] and by_id[i]["rust_version"] and v(by_id[i]["rust_version"]) > v(msrv)]
assert not bad, f"dependencies needing more than rust {msrv}: {bad}"
print(f"rust-version {msrv}: {len(seen)} crates in the published graph, the most demanding dependency needs {worst[0]} ({worst[1]})")
'

# 3. The published crates package cleanly (metadata, licence files, readme): any
#    warning fails. Verification (building each package) is left to the test build.
out=$(cargo package --locked --no-verify --allow-dirty -p heml-core -p heml-symbolic -p heml-derive -p heml-materials -p heml-integrators -p heml 2>&1)
if echo "$out" | grep -q '^warning'; then
  echo "$out" >&2
  echo "error: cargo package warns" >&2
  exit 1
fi
echo "$out" | grep Packaged

# 4. The wheel build reuses the test build: every crate in heml-py's dependency tree
#    gets, under `-p heml-py` (how pip/maturin build it), a feature set that the
#    workspace's build (`cargo test --workspace`) also compiles. A crate that fails
#    this is compiled again by pip, with everything above it (before
#    heml-workspace-hack: ~200 s of CI). Fix: `cargo install cargo-hakari`, then
#    `cargo hakari generate` (it rewrites heml-workspace-hack/Cargo.toml).
features() { cargo tree --locked "$@" -e normal,build -f '{p} [{f}]' --prefix none | sed 's/ (\*)$//' | grep -v '^heml-workspace-hack ' | sort -u; }
missing=$(comm -13 <(features --workspace -e dev) <(features -p heml-py))
if [ -n "$missing" ]; then
  echo "$missing" >&2
  echo "error: heml-py's build would compile these crates with other features than the workspace's (above): run cargo hakari generate" >&2
  exit 1
fi
echo "heml-py's $(features -p heml-py | wc -l) crate builds are all among the workspace's"

