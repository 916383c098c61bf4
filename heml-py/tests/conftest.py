"""Shared fixtures of the Python tests: the Rust run of tests/data/stretch.toml that
the bit-for-bit comparisons read, and the parameters of every built-in law."""

import os
import pathlib
import shutil
import subprocess

import pytest

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parents[1]
STRETCH_SCENE = HERE / "data" / "stretch.toml"
STRETCH_STEPS = 128  # duration / dt of the scene
STRETCH_DT = 6.103515625e-05

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


def _heml_cli():
    """The `heml` command of this repository: $HEML_CLI, target/release/heml, or
    `heml` on PATH."""
    for c in (os.environ.get("HEML_CLI"), str(REPO / "target" / "release" / "heml"), shutil.which("heml")):
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    return None


@pytest.fixture(scope="session")
def stretch_run(tmp_path_factory):
    """Output directory of the Rust run of STRETCH_SCENE (frame_00000.vtu at rest,
    frame_00001.vtu after the last step): the one heml-py/tests/pytest.rs made
    with the library ($HEML_RUST_RUN), else a `heml run` of the command."""
    given = os.environ.get("HEML_RUST_RUN")
    if given:
        return pathlib.Path(given)
    cli = _heml_cli()
    if cli is None:
        pytest.skip("no Rust run to compare with: set HEML_RUST_RUN, or build the `heml` command "
                    "(cargo build --release -p heml-cli) or set HEML_CLI")
    out = tmp_path_factory.mktemp("stretch")
    subprocess.run([cli, "run", str(STRETCH_SCENE), "--out", str(out), "--quiet"], check=True, timeout=300)
    return out
