//! Overlapping tets: a per-tet integration weight and cover.
//!
//! A mesh may hold several *covers* of the same body, each a conforming tiling on
//! its own, whose tets overlap: the symmetric ten-tet hex split
//! ([`super::generate::HexSplit::Ten`]) keeps both five-tet cuttings of every cell,
//! the two mirror images, so that neither's preferred face diagonals show. Each tet
//! then counts with a weight ω (½ for two covers) so that the body's energy, forces,
//! stiffness and mass are the average over the covers: every formulation integrates
//! ω·Vol·w(F) over the tet (the rest volume Vol keeps its geometric meaning, J =
//! vol/Vol), and mass is lumped from ω·Vol ([`TetMesh::weighted_volume`]).
//!
//! The weight is applied once, where every formulation's tet results are summed
//! (the block driver of `force::assembly`, and the tangent's per-tet stiffness),
//! so the per-formulation kernels need not know it; a mesh without overlap carries
//! nothing and is evaluated exactly as before.
//!
//! The boundary surface of overlapping covers is that of cover 0 alone
//! ([`super::surface::BoundarySurface::of_tet_mesh`]): each cover is a conforming
//! tiling of the same body, so cover 0's boundary is a closed, consistently
//! oriented manifold, whereas the faces used once over all covers would be every
//! cover's boundary on top of each other (two triangulations of each boundary
//! quad of a ten-split box).

use super::TetMesh;
use crate::error::{HemlError, Result};

/// Per-tet weights and covers of a mesh whose tets overlap (see the module doc).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Overlap {
    /// Integration weight ω of each tet, in (0, 1].
    pub weights: Vec<f64>,
    /// Cover of each tet: tets of one cover tile the body without overlapping; the
    /// boundary surface is that of cover 0.
    pub covers: Vec<u8>,
}

impl Overlap {
    /// `n` tets of weight 1 in cover 0: a mesh without overlap, to extend.
    pub fn plain(n: usize) -> Overlap {
        Overlap {
            weights: vec![1.0; n],
            covers: vec![0; n],
        }
    }

    /// Whether every tet has weight 1 and cover 0 (nothing to carry).
    pub fn is_plain(&self) -> bool {
        self.weights.iter().all(|&w| w == 1.0) && self.covers.iter().all(|&c| c == 0)
    }

    /// Checks the sizes against `n_tets` and the weights (finite, in (0, 1]).
    fn validate(&self, n_tets: usize) -> Result<()> {
        for (what, got) in [("tet weights", self.weights.len()), ("tet covers", self.covers.len())] {
            if got != n_tets {
                return Err(HemlError::SizeMismatch {
                    what,
                    got,
                    expected: n_tets,
                });
            }
        }
        if let Some(t) = self.weights.iter().position(|&w| !(w > 0.0 && w <= 1.0)) {
            return Err(HemlError::Mesh(format!(
                "tet {t} has weight {}; a tet weight must lie in (0, 1]",
                self.weights[t]
            )));
        }
        Ok(())
    }
}

impl TetMesh {
    /// The mesh with per-tet weights and covers (see the module doc). An overlap
    /// whose weights are all 1 and covers all 0 is dropped (the mesh is plain).
    ///
    /// ```
    /// use heml_core::mesh::overlap::Overlap;
    /// use heml_core::TetMesh;
    /// let unit = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
    /// let mesh = TetMesh::from_arrays(&unit, &[[0, 1, 2, 3], [0, 1, 2, 3]]).unwrap();
    /// let mesh = mesh.with_overlap(Overlap { weights: vec![0.5; 2], covers: vec![0, 1] }).unwrap();
    /// // two covers of one tet, each at half weight: the body's volume is the tet's
    /// assert!((mesh.total_volume() - 1.0 / 6.0).abs() < 1e-15);
    /// assert_eq!(mesh.tet_volume(1), 1.0 / 6.0);
    /// ```
    pub fn with_overlap(mut self, overlap: Overlap) -> Result<Self> {
        overlap.validate(self.n_tets())?;
        self.overlap = (!overlap.is_plain()).then_some(overlap);
        Ok(self)
    }

    /// The per-tet weights and covers, `None` for a mesh whose tets do not overlap.
    pub fn overlap(&self) -> Option<&Overlap> {
        self.overlap.as_ref()
    }

    /// Integration weight of tet `t` (1 unless the mesh has overlapping covers).
    #[inline]
    pub fn tet_weight(&self, t: usize) -> f64 {
        self.overlap.as_ref().map_or(1.0, |o| o.weights[t])
    }

    /// Cover of tet `t` (0 unless the mesh has overlapping covers).
    #[inline]
    pub fn tet_cover(&self, t: usize) -> u8 {
        self.overlap.as_ref().map_or(0, |o| o.covers[t])
    }

    /// ω·Vol of tet `t`: the volume it integrates energy and mass over.
    #[inline]
    pub fn weighted_volume(&self, t: usize) -> f64 {
        self.tet_weight(t) * self.tet_volume(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_weights_and_sizes_are_refused_and_plain_overlap_is_dropped() {
        let unit = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
        let m = TetMesh::from_arrays(&unit, &[[0, 1, 2, 3], [0, 1, 2, 3]]).unwrap();
        for w in [0.0, -0.5, 1.5, f64::NAN] {
            let e = m
                .clone()
                .with_overlap(Overlap {
                    weights: vec![0.5, w],
                    covers: vec![0, 1],
                })
                .unwrap_err()
                .to_string();
            assert!(e.contains("tet 1 has weight"), "{e}");
        }
        let e = m
            .clone()
            .with_overlap(Overlap {
                weights: vec![0.5],
                covers: vec![0, 1],
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("tet weights"), "{e}");
        let plain = m.clone().with_overlap(Overlap::plain(2)).unwrap();
        assert!(plain.overlap().is_none());
        assert_eq!(plain, m);
    }
}
