//! Fibre directions per tet, in the rest frame, for fibre-reinforced laws
//! ([`crate::law::FibreLaw`]): one or two unit vectors per tet (the fibre
//! families), indexed by global tet id. A scene gets them from mesh cell data, a
//! per-region constant or an expression of the tet's rest centroid; a library user
//! builds them with [`Fibres::new`] or [`Fibres::uniform`] and hands them to the law
//! with [`crate::Material::with_fibres`].

use crate::error::{HemlError, Result};
use crate::Vec3;

/// Unit fibre directions of every tet of a mesh (one or two families).
#[derive(Debug, Clone, PartialEq)]
pub struct Fibres {
    families: usize,
    dirs: Vec<[Vec3; 2]>,
}

impl Fibres {
    /// Fibres from per-tet directions `dirs[t][k]` of family `k < families`
    /// (`families` is 1 or 2; the second vector of each tet is ignored for one
    /// family). Each direction is normalised; a zero, non-finite or (for one
    /// family) missing direction is an error naming the tet.
    ///
    /// ```
    /// use heml_core::{fibres::Fibres, Vec3};
    /// let f = Fibres::new(1, vec![[Vec3::new(2.0, 0.0, 0.0), Vec3::zeros()]]).unwrap();
    /// assert_eq!(f.dir(0, 0), Vec3::x());
    /// assert!(Fibres::new(1, vec![[Vec3::zeros(); 2]]).is_err());
    /// ```
    pub fn new(families: usize, mut dirs: Vec<[Vec3; 2]>) -> Result<Self> {
        if !(1..=2).contains(&families) {
            return Err(HemlError::Invalid(format!(
                "{families} fibre families: a fibre law has 1 or 2"
            )));
        }
        for (t, d) in dirs.iter_mut().enumerate() {
            for (k, a) in d.iter_mut().enumerate().take(families) {
                let n = a.norm();
                if !(n.is_finite() && n > 1e-300 && a.iter().all(|c| c.is_finite())) {
                    return Err(HemlError::Invalid(format!(
                        "tet {t}: fibre direction {} of family {} is not a non-zero finite vector",
                        fmt_vec(a),
                        k + 1
                    )));
                }
                *a /= n;
            }
            if families == 1 {
                d[1] = d[0];
            }
        }
        Ok(Self { families, dirs })
    }

    /// The same directions `dirs` (one per family) in each of `n_tets` tets.
    pub fn uniform(n_tets: usize, dirs: &[Vec3]) -> Result<Self> {
        let d = match dirs {
            [a] => [*a, *a],
            [a, b] => [*a, *b],
            _ => {
                return Err(HemlError::Invalid(format!(
                    "{} fibre directions given: a fibre law has 1 or 2 families",
                    dirs.len()
                )))
            }
        };
        Self::new(dirs.len(), vec![d; n_tets])
    }

    /// Number of families (1 or 2).
    pub fn families(&self) -> usize {
        self.families
    }

    /// Number of tets covered.
    pub fn n_tets(&self) -> usize {
        self.dirs.len()
    }

    /// Unit direction of family `k` in tet `t` (family 0 for a missing second).
    pub fn dir(&self, t: usize, k: usize) -> Vec3 {
        self.dirs[t][k.min(1)]
    }

    /// Checks that the fibres cover a mesh of `n_tets` tets and give at least the
    /// `families` a law needs (`law` names it in the error).
    pub fn check(&self, law: &str, n_tets: usize, families: usize) -> Result<()> {
        if self.dirs.len() != n_tets {
            return Err(HemlError::Invalid(format!(
                "law {law}: fibre directions cover {} tets, the mesh has {n_tets}",
                self.dirs.len()
            )));
        }
        if self.families < families {
            return Err(HemlError::Invalid(format!(
                "law {law} has {families} fibre families, {} direction(s) per tet were given",
                self.families
            )));
        }
        Ok(())
    }
}

fn fmt_vec(a: &Vec3) -> String {
    format!("[{}, {}, {}]", a.x, a.y, a.z)
}
