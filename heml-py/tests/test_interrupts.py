"""Long calls that release the GIL can be stopped: Ctrl-C (a pending signal) and an
exception of the progress callback end them promptly; a system or scene held by a
running call is refused with a message that says why.

The Ctrl-C tests run in a child process (a KeyboardInterrupt that arrived late
would hit pytest itself), each bounded by a timeout."""

import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import heml

# A tiny scene: about 450 steps per simulated second, ~2 µs each (a duration of
# 10^5 s runs for over a minute).
LONG_SCENE = """
[mesh]
generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }
[[material]]
law = "neo_hookean"
params = { E = 5e3, nu = 0.3 }
[[fix]]
plane = { point = [0, 0, 0], normal = [1, 0, 0] }
[loads]
gravity = [0, 0, -9.81]
[solver]
duration = %s
[output]
vtu = false
csv = false
"""


def interrupted_in_child(body):
    """Runs `body` (Python source using `heml`, `np`, `time`) in a child process
    whose main thread gets a simulated Ctrl-C 0.3 s in; returns the child's stdout.
    The child prints "interrupted after <seconds>" when KeyboardInterrupt reaches it."""
    code = textwrap.dedent("""
        import _thread, threading, time
        import numpy as np, heml
        threading.Timer(0.3, _thread.interrupt_main).start()
        start = time.monotonic()
        try:
        %s
        except KeyboardInterrupt:
            print("interrupted after %%.2f" %% (time.monotonic() - start))
    """) % textwrap.indent(textwrap.dedent(body), "    ")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1"))
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def assert_prompt(out):
    assert out.startswith("interrupted after"), out
    # 0.3 s in, checked every 0.1 s: well under the minutes the call would take
    assert float(out.split()[-1]) < 5.0, out


def test_ctrl_c_stops_a_static_solve():
    """Dynamic relaxation of a mass-spring beam to 1e-12: ~8000 iterations per
    second here, far from converging in 10^7; Ctrl-C ends it within ~0.1 s."""
    assert_prompt(interrupted_in_child("""
        mesh = heml.box_mesh([0.1, 0.02, 0.02], [20, 6, 6])
        s = heml.System(mesh, "mass_spring", {"k": 50.0}, gravity=[0, 0, -9.81], fixed=mesh.nodes[:, 0] == 0)
        s.solve_static(tol=1e-12, max_iterations=10**7)
        print("returned")
    """))


def test_ctrl_c_stops_a_scene_run_without_callback():
    assert_prompt(interrupted_in_child("""
        heml.Scene.from_toml('''%s''').run()
        print("returned")
    """ % (LONG_SCENE % "1.0e5")))


def test_a_raising_callback_ends_the_run_at_once():
    """The callback raises at step 2: the run ends there (it used to go on to its
    duration, 23 steps), and the exception is raised."""
    calls = []

    def cb(p):
        calls.append(p["step"])
        if p["step"] == 2:
            raise KeyboardInterrupt

    scene = heml.Scene.from_toml(LONG_SCENE % "0.05")
    with pytest.raises(KeyboardInterrupt):
        scene.run(progress=cb)
    assert calls == [1, 2]
    # the state reached is the scene's: step 2 of 23
    assert 0 < scene.time < 0.05 / 5


def test_solve_static_reports_its_roundoff_level():
    mesh = heml.box_mesh([0.1, 0.02, 0.02], [4, 2, 2])
    s = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45), fixed=mesh.nodes[:, 0] == 0)
    r = s.solve_static()  # unloaded: at equilibrium as it is
    assert r["converged"] and r["roundoff"] >= 0.0
    assert set(r) == set(heml.StaticReport.__annotations__)


def test_a_system_stepping_in_another_thread_is_refused_with_a_clear_message():
    """While a thread is inside `step` (GIL released), reading the system from
    another thread raises RuntimeError saying so (it was PyO3's 'Already mutably
    borrowed'). Polled until the stepping thread ends."""
    mesh = heml.box_mesh([0.1, 0.05, 0.05], [16, 8, 8])
    s = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45), fixed=mesh.nodes[:, 0] == 0)
    t = threading.Thread(target=s.step, kwargs=dict(integrator="symplectic_euler", n=1000))
    t.start()
    messages = set()
    while t.is_alive():
        try:
            s.positions
        except RuntimeError as e:
            messages.add(str(e))
    t.join()
    assert messages, "the step ended before the system was read"
    assert all("the system is stepping in another thread" in m for m in messages), messages
    assert s.step_count == 1000 and np.all(np.isfinite(s.positions))


def test_reading_the_scene_from_its_own_callback_says_so():
    seen = []

    def cb(p):
        try:
            _ = heml_scene.positions
        except RuntimeError as e:
            seen.append(str(e))
            raise

    heml_scene = heml.Scene.from_toml(LONG_SCENE % "0.05")
    with pytest.raises(RuntimeError, match="inside its own progress callback"):
        heml_scene.run(progress=cb)
    assert len(seen) == 1 and "another thread" not in seen[0]
    assert heml_scene.positions.shape == (12, 3)  # readable once run() returned
