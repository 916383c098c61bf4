"""Laws declared at run time from Python: the forces of the built-in law with the
same energy, and errors that point into the text."""

import numpy as np
import pytest

import heml

NEO_HOOKEAN = "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)"


def deformed(mesh, seed=1):
    """A smooth stretch and shear plus a random perturbation (no tet inverted)."""
    rng = np.random.default_rng(seed)
    x = mesh.nodes @ np.array([[1.1, 0.05, 0.0], [0.0, 0.95, 0.02], [0.0, 0.0, 1.03]])
    size = np.ptp(mesh.nodes, axis=0).max()
    return x + 0.005 * size * rng.standard_normal(x.shape)


def test_runtime_neo_hookean_has_the_built_in_forces():
    """Same energy, same exact derivatives, same operations: the forces agree to
    1e-12 of the largest (the Rust tests find them equal to the bit; the margin
    allows a different summation order of a future kernel, while a wrong term would
    be O(1) relative)."""
    mesh = heml.box_mesh([0.1, 0.05, 0.05], [4, 2, 2])
    built_in = heml.material("neo_hookean", mu=1e3, **{"lambda": 4e3})
    runtime = heml.material_from_energy(NEO_HOOKEAN, mu=1e3, **{"lambda": 4e3})
    assert runtime.energy == NEO_HOOKEAN and runtime.kind == "invariant"
    assert runtime.params == {"lambda": 4e3, "mu": 1e3}
    x = deformed(mesh)
    e_ref, f_ref = built_in.force_field(mesh).forces(x)
    e, f = runtime.force_field(mesh).forces(x)
    scale = np.abs(f_ref).max()
    assert scale > 0 and e_ref > 0
    assert np.abs(f - f_ref).max() <= 1e-12 * scale
    assert abs(e - e_ref) <= 1e-12 * e_ref


def test_syntax_error_raises_with_the_column():
    with pytest.raises(heml.HemlError, match=r"column 6: `\(` is never closed"):
        heml.material_from_energy("mu/2*(I1-3 - mu*ln(J)", mu=1.0)


def test_unknown_word_names_the_column_and_a_suggestion():
    with pytest.raises(heml.HemlError, match=r"column 15: unknown identifier `lamda`.*did you mean `lambda`"):
        heml.material_from_energy("mu/2*(I1-3) + lamda*J", mu=1.0, **{"lambda": 2.0})


def test_unused_parameter_and_bad_value_raise():
    with pytest.raises(heml.HemlError, match="'kappa' given but not used"):
        heml.material_from_energy("mu/2*(I1-3)", mu=1.0, kappa=2.0)
    with pytest.raises(TypeError, match="must be a number"):
        heml.material_from_energy("mu/2*(I1-3)", mu="soft")
