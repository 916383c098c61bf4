//! The volumetric energy at **grouped** volume ratios, written once for both
//! anti-locking formulations: with the split w = w_iso + U(J) of
//! [`super::volumetric`], volume groups g, tet weights ω_t and shares q_{t,g},
//!
//! W = Σ_t Vol_t [w_iso,t + β U(J_t)] + (1 − β) Σ_g V_g U(J_g),
//! V_g = Σ_{t∋g} q ω_t Vol_t, v_g = Σ_{t∋g} q ω_t vol_t, J_g = v_g / V_g,
//!
//! f = −[element part] − Σ_t ω_t p̄_t ∇vol_t, p̄_t = q Σ_{g∋t} (1 − β) U′(J_g).
//!
//! The **nodal** term ([`super::nodal_volume`]) groups by node (a tet gives q = ¼
//! to each of its four corners), the **patch** term ([`super::patch_volume`]) by
//! compact patches of about k tets (q = 1 to its one patch). What differs — the
//! group map and how the batched pass obtains the group volumes (a global sweep
//! before the element pass, or per block between its two phases) — is a
//! [`VolumeGroups`]; the rest is here once: the law's pressure loop
//! ([`GroupLaw`]), the force field with its tet-by-tet reference path
//! ([`GroupedVolumeField`]), the matrix-free tangent ([`GroupedVolumeTangent`]) and
//! the material plumbing (`build`).

mod build;
mod field;
mod geometry;
mod groups;
mod law;
mod tangent;

pub(crate) use build::{group_weight, VolumeTerm};
pub(crate) use field::different_tets;
pub use field::GroupedVolumeField;
pub(crate) use geometry::volume;
pub use groups::{TetGroups, VolumeGroups};
pub use law::{element_fraction, GroupLaw, DEFAULT_STABILIZATION};
pub use tangent::GroupedVolumeTangent;
