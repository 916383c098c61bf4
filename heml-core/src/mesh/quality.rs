//! Element quality: the numbers that predict trouble before a simulation starts —
//! flat or needle-like tets make the explicit time step tiny and the P1 solution
//! poor.

use crate::mesh::TetMesh;
use crate::rest::EDGES;
use crate::Vec3;

/// Quality measures of one tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetQuality {
    /// Smallest of the six dihedral angles (radians).
    pub min_dihedral: f64,
    /// Largest of the six dihedral angles (radians).
    pub max_dihedral: f64,
    /// Smallest height: 3·volume / largest face area. Sets the explicit time step.
    pub min_height: f64,
    /// Longest edge over smallest height, scaled so that a regular tet has 1.
    pub aspect_ratio: f64,
    /// 3·inradius / circumradius: 1 for a regular tet, → 0 for slivers.
    pub radius_ratio: f64,
}

/// Faces opposite each vertex.
const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// Quality of the tet with vertices `p` (any orientation).
pub fn tet_quality(p: &[Vec3; 4]) -> TetQuality {
    let vol = ((p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0).abs();
    let areas = FACES.map(|[a, b, c]| 0.5 * (p[b] - p[a]).cross(&(p[c] - p[a])).norm());
    let amax = areas.iter().copied().fold(0.0, f64::max);
    let min_height = 3.0 * vol / amax;
    let lmax = EDGES.iter().map(|&(a, b)| (p[b] - p[a]).norm()).fold(0.0, f64::max);
    let (mut min_dihedral, mut max_dihedral) = (f64::INFINITY, 0.0_f64);
    for (i, j) in EDGES {
        let (k, l) = other_two(i, j);
        let e = (p[j] - p[i]).normalize();
        let u = (p[k] - p[i]) - e * e.dot(&(p[k] - p[i]));
        let w = (p[l] - p[i]) - e * e.dot(&(p[l] - p[i]));
        let angle = u.cross(&w).norm().atan2(u.dot(&w));
        min_dihedral = min_dihedral.min(angle);
        max_dihedral = max_dihedral.max(angle);
    }
    let inradius = 3.0 * vol / areas.iter().sum::<f64>();
    let (a, b, c) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let circumradius =
        (b.cross(&c) * a.norm_squared() + c.cross(&a) * b.norm_squared() + a.cross(&b) * c.norm_squared()).norm()
            / (12.0 * vol);
    TetQuality {
        min_dihedral,
        max_dihedral,
        min_height,
        aspect_ratio: lmax / min_height * (2.0_f64 / 3.0).sqrt(),
        radius_ratio: 3.0 * inradius / circumradius,
    }
}

fn other_two(i: usize, j: usize) -> (usize, usize) {
    let mut rest = (0..4).filter(|&v| v != i && v != j);
    (rest.next().unwrap_or(0), rest.next().unwrap_or(0))
}

/// Worst values over a mesh, with the id of the tet where each occurs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshQuality {
    /// Smallest dihedral angle (radians) and its tet.
    pub min_dihedral: (f64, usize),
    /// Largest dihedral angle (radians) and its tet.
    pub max_dihedral: (f64, usize),
    /// Smallest height and its tet.
    pub min_height: (f64, usize),
    /// Largest aspect ratio and its tet.
    pub max_aspect_ratio: (f64, usize),
    /// Smallest radius ratio and its tet.
    pub min_radius_ratio: (f64, usize),
    /// Shortest and longest edge length.
    pub edge_length: (f64, f64),
}

/// Quality summary over the tets `tets` of `mesh` (all when `None`); `None` for an
/// empty selection.
pub fn mesh_quality(mesh: &TetMesh, tets: Option<&[usize]>) -> Option<MeshQuality> {
    let all: Vec<usize>;
    let ids = match tets {
        Some(ids) => ids,
        None => {
            all = (0..mesh.n_tets()).collect();
            &all
        }
    };
    let first = *ids.first()?;
    let q0 = tet_quality(&mesh.tet_points(first));
    let mut out = MeshQuality {
        min_dihedral: (q0.min_dihedral, first),
        max_dihedral: (q0.max_dihedral, first),
        min_height: (q0.min_height, first),
        max_aspect_ratio: (q0.aspect_ratio, first),
        min_radius_ratio: (q0.radius_ratio, first),
        edge_length: (f64::INFINITY, 0.0),
    };
    for &t in ids {
        let p = mesh.tet_points(t);
        let q = tet_quality(&p);
        let lower = |slot: &mut (f64, usize), v: f64| {
            if v < slot.0 {
                *slot = (v, t)
            }
        };
        lower(&mut out.min_dihedral, q.min_dihedral);
        lower(&mut out.min_height, q.min_height);
        lower(&mut out.min_radius_ratio, q.radius_ratio);
        if q.max_dihedral > out.max_dihedral.0 {
            out.max_dihedral = (q.max_dihedral, t);
        }
        if q.aspect_ratio > out.max_aspect_ratio.0 {
            out.max_aspect_ratio = (q.aspect_ratio, t);
        }
        for (a, b) in EDGES {
            let l = (p[b] - p[a]).norm();
            out.edge_length = (out.edge_length.0.min(l), out.edge_length.1.max(l));
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed forms: a regular tet has all dihedral angles arccos(1/3), height
    /// a·√(2/3), aspect and radius ratios 1; the corner tet of a unit cube has three
    /// right dihedral angles and height 1/√3. Bound: a few ulps of each formula.
    #[test]
    fn closed_form_tets() {
        let s = 1.0 / 2.0_f64.sqrt();
        let regular = [
            Vec3::new(1.0, 0.0, -s),
            Vec3::new(-1.0, 0.0, -s),
            Vec3::new(0.0, 1.0, s),
            Vec3::new(0.0, -1.0, s),
        ];
        let q = tet_quality(&regular);
        let a = 2.0; // edge length
        for angle in [q.min_dihedral, q.max_dihedral] {
            assert!((angle - (1.0_f64 / 3.0).acos()).abs() < 1e-12);
        }
        assert!((q.min_height - a * (2.0_f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((q.aspect_ratio - 1.0).abs() < 1e-12 && (q.radius_ratio - 1.0).abs() < 1e-12);

        let corner = [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        let q = tet_quality(&corner);
        assert!((q.max_dihedral - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((q.min_dihedral - (1.0_f64 / 3.0).sqrt().acos()).abs() < 1e-12);
        assert!((q.min_height - 1.0 / 3.0_f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn slivers_are_singled_out() {
        let sliver = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 0.0, 0.01),
            Vec3::new(0.0, 1.0, 0.01),
        ];
        let good = [
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(3.0, 1.0, 0.0),
            Vec3::new(3.0, 0.0, 1.0),
        ];
        let nodes: Vec<[f64; 3]> = good.iter().chain(&sliver).map(|p| [p.x, p.y, p.z]).collect();
        let mesh = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 3], [4, 5, 6, 7]]).unwrap();
        let q = mesh_quality(&mesh, None).unwrap();
        assert_eq!(q.min_radius_ratio.1, 1);
        assert!(q.min_radius_ratio.0 < 0.05, "{q:?}");
        assert_eq!(q.max_dihedral.1, 1);
        assert!(q.max_dihedral.0 > 3.0, "{q:?}"); // nearly flat: close to π
        assert_eq!(q.min_height.1, 1);
        assert!(mesh_quality(&mesh, Some(&[])).is_none());
    }
}
