use heml_derive::material;

/// Mass–spring, the degenerate HEML law: one spring per tetrahedron edge with energy
/// ½k(√l − √L)² (l, L the current and rest squared lengths), whose force is the
/// classical k(|v| − L)·v/|v|.
///
/// An edge shared by n tets carries n springs (stiffness n·k in all).
/// Reference: Goulette et al., HEML (2015), §"mass–spring as a special case".
#[material(name = "mass_spring", link)]
#[energy(k / 2.0 * (l.sqrt() - L.sqrt()).powi(2))]
pub struct MassSpring {
    /// Spring stiffness k per tet edge (N/m).
    pub k: f64,
}
