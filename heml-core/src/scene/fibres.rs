//! The fibre directions of a `[[material]]` with a fibre law: a constant per
//! region (`fibres`) or a helix around an axis (`fibre_helix`), evaluated at every
//! tet's rest centroid (only the region's tets are read by its force field).

use super::schema::MaterialSpec;
use crate::error::{HemlError, Result};
use crate::fibres::Fibres;
use crate::mesh::TetMesh;
use crate::Vec3;

/// The fibres of material `m` on `mesh`, checked against the law's `families`
/// (0: not a fibre law, which may not have fibre keys).
pub(super) fn material_fibres(m: &MaterialSpec, mesh: &TetMesh, families: usize) -> Result<Option<Fibres>> {
    let given = usize::from(m.fibres.is_some()) + usize::from(m.fibre_helix.is_some());
    let invalid = |msg: String| Err(HemlError::Invalid(msg));
    match (families, given) {
        (0, 0) => return Ok(None),
        (0, _) => {
            return invalid(format!(
                "law {} is not a fibre law: remove `fibres`/`fibre_helix`",
                m.law
            ))
        }
        (_, 0) => {
            return invalid(format!(
                "law {} is fibre-reinforced ({families} famil{}): give its directions with \
                 `fibres = [[x, y, z]{}]` or `fibre_helix = {{ axis = [..], angle = deg }}`",
                m.law,
                if families == 1 { "y" } else { "ies" },
                if families == 2 { ", [x, y, z]" } else { "" }
            ))
        }
        (_, 2) => return invalid("give `fibres` or `fibre_helix`, not both".into()),
        _ => {}
    }
    if let Some(dirs) = &m.fibres {
        if dirs.len() < families || dirs.len() > 2 {
            return invalid(format!(
                "`fibres` has {} direction(s); law {} has {families} fibre famil{}",
                dirs.len(),
                m.law,
                if families == 1 { "y" } else { "ies" }
            ));
        }
        let v: Vec<Vec3> = dirs.iter().map(|d| Vec3::from(*d)).collect();
        return Fibres::uniform(mesh.n_tets(), &v)
            .map(Some)
            .map_err(|e| HemlError::Invalid(format!("`fibres`: {e}")));
    }
    let h = m.fibre_helix.expect("one source is given");
    let axis = Vec3::from(h.axis);
    if !(axis.norm() > 0.0 && axis.iter().all(|c| c.is_finite())) || !h.angle.is_finite() {
        return invalid(format!(
            "`fibre_helix`: axis {:?} must be a non-zero finite vector and angle {} finite",
            h.axis, h.angle
        ));
    }
    let axis = axis.normalize();
    let origin = Vec3::from(h.origin);
    let (s, c) = h.angle.to_radians().sin_cos();
    let dirs = (0..mesh.n_tets())
        .map(|t| {
            let p = mesh.tet_points(t);
            let centroid = (p[0] + p[1] + p[2] + p[3]) / 4.0;
            let r = centroid - origin;
            let radial = r - axis * axis.dot(&r);
            if radial.norm() <= 1e-12 * r.norm().max(1e-300) {
                return Err(HemlError::Invalid(format!(
                    "`fibre_helix`: tet {t} has its centroid on the axis, where the circumferential direction is undefined"
                )));
            }
            let theta = axis.cross(&radial).normalize();
            Ok([theta * c + axis * s, theta * c - axis * s])
        })
        .collect::<Result<Vec<_>>>()?;
    Fibres::new(2, dirs).map(Some)
}
