"""Shared fixtures of the Python tests: the `heml` command (for comparisons with the
Rust run) and a small scene both sides run."""

import os
import pathlib
import shutil
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]

# Parameters of every built-in law for the tests that loop over laws: soft-tissue
# magnitudes, E/nu where the law maps them.
LAW_PARAMS = {
    "neo_hookean": dict(E=3e3, nu=0.45),
    "stable_neo_hookean": dict(E=3e3, nu=0.45),
    "saint_venant_kirchhoff": dict(E=3e3, nu=0.3),
    "mooney_rivlin": dict(E=3e3, nu=0.45, c01=200.0),
    "fung_demiray": dict(E=3e3, nu=0.45, b=2.0),
    "yeoh": dict(E=3e3, nu=0.45, c2=100.0, c3=10.0),
    "gent": dict(E=3e3, nu=0.45, jm=5.0),
    "arruda_boyce": dict(E=3e3, nu=0.45, lm=3.0),
    "veronda_westmann": dict(E=3e3, nu=0.45, c2=1.5),
    "mass_spring": dict(k=50.0),
}


@pytest.fixture(scope="session")
def heml_cli():
    """Path of the `heml` command built from this repository: $HEML_CLI, else
    target/release/heml, else `heml` on PATH; the comparison tests skip (saying
    so) when there is none."""
    candidates = [os.environ.get("HEML_CLI"), str(REPO / "target" / "release" / "heml"), shutil.which("heml")]
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    pytest.skip("no `heml` command found (build it: cargo build --release -p heml-cli, or set HEML_CLI)")


# A 4 × 2 × 2 cm block clamped at x = 0 whose far face is pulled (smooth ramp),
# no gravity or damping, so that the frames' force/reaction fields are the
# elastic forces alone. Kept in file order (renumber = false) so that node and
# tet order, hence every floating-point sum, is the same on both sides. Duration
# and dt are powers of two so that duration / steps is exactly dt.
STRETCH_SCENE = """
[mesh]
generate = {{ kind = "box", size = [0.04, 0.02, 0.02], cells = [4, 2, 2] }}
renumber = false
[[material]]
law = "neo_hookean"
params = {{ E = 5e3, nu = 0.45 }}
density = 1000.0
[[fix]]
plane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}
[[prescribe]]
plane = {{ point = [0.04, 0, 0], normal = [1, 0, 0] }}
displacement = [0.008, 0.002, 0.0]
ramp = {{ kind = "smooth", duration = 0.005 }}
[solver]
integrator = "velocity_verlet"
duration = 0.0078125
dt = 6.103515625e-05
dt_policy = "warn"
[output]
dir = "{out}"
every = 128
csv = false
compression = "none"
precision = "double"
"""

STRETCH_STEPS = 128
STRETCH_DT = 6.103515625e-05


@pytest.fixture(scope="session")
def stretch_run(tmp_path_factory, heml_cli):
    """Runs STRETCH_SCENE with the `heml` command; returns (scene path, output dir)."""
    d = tmp_path_factory.mktemp("stretch")
    out = d / "out"
    scene = d / "stretch.toml"
    scene.write_text(STRETCH_SCENE.format(out=out.as_posix()))
    subprocess.run([heml_cli, "run", str(scene), "--quiet"], check=True, timeout=300)
    return scene, out
