//! The fibre directions of a `[[material]]` with a fibre law: a constant per
//! region (`fibres`), a helix around an axis (`fibre_helix`), expressions of the
//! position (`fibre_expressions`), evaluated at every tet's rest centroid (only the
//! region's tets are read by its force field), or cell fields of the mesh file.

use super::fibre_expr::DirectionExpr;
use super::schema::MaterialSpec;
use crate::error::{HemlError, Result};
use crate::fibres::Fibres;
use crate::io::MeshData;
use crate::mesh::TetMesh;
use crate::Vec3;
use std::path::Path;

/// Fails when a material's `fibre_fields` names a cell field of the mesh file
/// `path` that cannot give a direction per cell ([`MeshData::vector_defects`]: a
/// zero or non-finite vector, a cell without a value, not 3 components), naming
/// the file, the field and the element as the file numbers it.
pub(super) fn check_fibre_fields(materials: &[MaterialSpec], data: &MeshData, path: &Path) -> Result<()> {
    for m in materials {
        for name in m.fibre_fields.iter().flatten() {
            if let Some(why) = data.vector_defects.get(name) {
                return Err(HemlError::Invalid(format!(
                    "`fibre_fields`: {}: cell field '{name}' cannot give fibre directions: {why}",
                    path.display()
                )));
            }
        }
    }
    Ok(())
}

/// The fibres of material `m` on `mesh`, checked against the law's `families`
/// (0: not a fibre law, which may not have fibre keys).
pub(super) fn material_fibres(m: &MaterialSpec, mesh: &TetMesh, families: usize) -> Result<Option<Fibres>> {
    let given = usize::from(m.fibres.is_some())
        + usize::from(m.fibre_helix.is_some())
        + usize::from(m.fibre_fields.is_some())
        + usize::from(m.fibre_expressions.is_some());
    let invalid = |msg: String| Err(HemlError::Invalid(msg));
    match (families, given) {
        (0, 0) => return Ok(None),
        (0, _) => {
            return invalid(format!(
                "law {} is not a fibre law: remove `fibres`/`fibre_helix`/`fibre_fields`/`fibre_expressions`",
                m.law
            ))
        }
        (_, 0) => {
            return invalid(format!(
                "law {} is fibre-reinforced ({families} famil{}): give its directions with \
                 `fibres = [[x, y, z]{}]`, `fibre_helix = {{ axis = [..], angle = deg }}`, \
                 `fibre_fields = [\"<cell field>\"]` or `fibre_expressions = [[\"-y\", \"x\", \"0\"]]`",
                m.law,
                if families == 1 { "y" } else { "ies" },
                if families == 2 { ", [x, y, z]" } else { "" }
            ))
        }
        (_, 1) => {}
        _ => return invalid("give one of `fibres`, `fibre_helix`, `fibre_fields` and `fibre_expressions`".into()),
    }
    // tets outside a tagged region are never read: any unit vector will do there
    let outside = |t: usize| m.tag.is_some_and(|tag| mesh.tags()[t] != tag);
    if let Some(names) = &m.fibre_fields {
        if names.len() < families || names.len() > 2 {
            return invalid(format!(
                "`fibre_fields` names {} field(s); law {} has {families} fibre famil{}",
                names.len(),
                m.law,
                if families == 1 { "y" } else { "ies" }
            ));
        }
        let fields = names
            .iter()
            .map(|n| {
                mesh.cell_vectors().get(n).ok_or_else(|| {
                    let known: Vec<&String> = mesh.cell_vectors().keys().collect();
                    HemlError::Invalid(format!(
                        "`fibre_fields`: the mesh has no 3-component cell field '{n}' (it has {known:?})"
                    ))
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let dirs = (0..mesh.n_tets())
            .map(|t| {
                if outside(t) {
                    [Vec3::x(); 2]
                } else {
                    [fields[0][t], fields[fields.len() - 1][t]]
                }
            })
            .collect();
        return Fibres::new(names.len(), dirs)
            .map(Some)
            .map_err(|e| HemlError::Invalid(format!("`fibre_fields` {names:?}: {e}")));
    }
    if let Some(texts) = &m.fibre_expressions {
        if texts.len() < families || texts.len() > 2 {
            return invalid(format!(
                "`fibre_expressions` has {} direction(s); law {} has {families} fibre famil{}",
                texts.len(),
                m.law,
                if families == 1 { "y" } else { "ies" }
            ));
        }
        let exprs = texts
            .iter()
            .enumerate()
            .map(|(k, t)| DirectionExpr::parse(t, k))
            .collect::<Result<Vec<_>>>()?;
        let dirs = (0..mesh.n_tets())
            .map(|t| {
                if outside(t) {
                    return Ok([Vec3::x(); 2]);
                }
                let p = mesh.tet_points(t);
                let c = (p[0] + p[1] + p[2] + p[3]) / 4.0;
                let mut d = [Vec3::x(); 2];
                for (k, e) in exprs.iter().enumerate() {
                    let a = Vec3::from(e.at([c.x, c.y, c.z]).map_err(|why| {
                        HemlError::Invalid(format!(
                            "`fibre_expressions`, family {}: at tet {t} (centroid {:?} m): {why}",
                            k + 1,
                            [c.x, c.y, c.z]
                        ))
                    })?);
                    let n = a.norm();
                    if !(n > 0.0 && n.is_finite()) {
                        return Err(HemlError::Invalid(format!(
                            "`fibre_expressions`, family {}: the direction at tet {t} (centroid {:?} m) is {:?}, \
                             which has no direction",
                            k + 1,
                            [c.x, c.y, c.z],
                            [a.x, a.y, a.z]
                        )));
                    }
                    d[k] = a / n;
                }
                if exprs.len() == 1 {
                    d[1] = d[0];
                }
                Ok(d)
            })
            .collect::<Result<Vec<_>>>()?;
        return Fibres::new(exprs.len(), dirs).map(Some);
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
    if !(axis.norm() > 0.0 && axis.iter().all(|c| c.is_finite()) && h.angle.is_finite()) {
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
