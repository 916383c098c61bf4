//! Runtime control of the laws: a region's material replaced between steps (a
//! stiffness slider in a simulator, a parameter study on one running state).
//!
//! Why not rebuild the system: a rebuilt system starts from the mesh, so it loses
//! what happened since it was built — the tets cuts removed, grasps, tools, surface
//! loads, runtime constraints and the viscous history. Only the region's force field
//! depends on the law; it is rebuilt here over the region's remaining tets and the
//! rest stays.

use crate::error::{HemlError, Result};
use crate::material::Material;
use crate::system::stability::critical_time_step;
use crate::system::System;

impl System {
    /// Replaces the law of region `region` (an index into [`System::regions`])
    /// between steps, keeping the state and every runtime change: cuts, grasps,
    /// tools, loads, constraints and the Prony history. The region's force field is
    /// rebuilt over its remaining tets with the system's force options, the stable
    /// step is estimated again (a stiffer law lowers it), the forces of the current
    /// state are recomputed by the next evaluation, and an implicit solver rebuilds
    /// its tangents at its next step. Density and Prony terms are the region's and
    /// stay.
    ///
    /// Errors, with the system unchanged: inside a step, an unknown region, or a law
    /// that cannot build a field on the region's tets (a fibre law without fibre
    /// directions, for instance).
    ///
    /// Without cuts, the system then steps bit for bit like one built with the new
    /// law and given the same state; after cuts, like one whose field was built on
    /// the remaining tets (the same forces up to the order of the additions).
    ///
    /// # Example
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::system::System;
    /// use heml_core::{material::Link, Vec3};
    /// # use heml_core::law::*;
    /// # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
    /// # impl MaterialInfo for Spring {
    /// #     const NAME: &'static str = "doc_spring"; const PARAMS: &'static [ParamInfo] = &[];
    /// #     const ENERGY: &'static str = ""; const DOC: &'static str = "";
    /// #     fn to_params(&self) -> Vec<f64> { vec![self.k] }
    /// #     fn from_params(v: &[f64]) -> Self { Spring { k: v[0] } }
    /// # }
    /// # impl LinkLaw for Spring {
    /// #     const OPS: OpCount = OpCount { add: 0, mul: 0, div: 0, func: 0 };
    /// #     fn w(&self, l: f64, r: f64) -> f64 { 0.5 * self.k * (l.sqrt() - r.sqrt()).powi(2) }
    /// #     fn dw(&self, l: f64, r: f64) -> (f64, f64) { (self.w(l, r), 0.5 * self.k * (1.0 - (r / l).sqrt())) }
    /// #     fn d2w(&self, l: f64, r: f64) -> f64 { 0.25 * self.k * r.sqrt() / (l * l.sqrt()) }
    /// # }
    /// let mesh = box_mesh([0.04, 0.01, 0.01], [8, 2, 2], HexSplit::Six)?;
    /// let mut sys = System::builder(mesh)
    ///     .material_law(Box::new(Link(Spring { k: 50.0 })))
    ///     .fix_where(|p| p.x < 1e-9)
    ///     .build()?;
    /// sys.remove_tets(&[0, 1])?; // a cut
    /// // the same law again: the stable step estimated anew, on the cut body
    /// sys.set_material(0, Box::new(Link(Spring { k: 50.0 })))?;
    /// let dt = sys.stable_dt();
    /// // four times as stiff: half the stable step, and the cut stays
    /// sys.set_material(0, Box::new(Link(Spring { k: 200.0 })))?;
    /// assert!((sys.stable_dt() / dt - 0.5).abs() < 1e-6);
    /// assert_eq!(sys.n_tets_alive(), sys.mesh().n_tets() - 2);
    /// assert!(sys.set_material(1, Box::new(Link(Spring { k: 1.0 }))).is_err());
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn set_material(&mut self, region: usize, material: Box<dyn Material>) -> Result<()> {
        self.set_materials(vec![(region, material)])
    }

    /// [`System::set_material`] for several regions at once: every field is built
    /// before any is replaced, so an error leaves all of them as they were. A region
    /// named twice is an error.
    pub fn set_materials(&mut self, laws: Vec<(usize, Box<dyn Material>)>) -> Result<()> {
        self.check_between_steps("set_material")?;
        let n = self.model.regions.len();
        let mut seen = vec![false; n];
        for (r, _) in &laws {
            if *r >= n {
                return Err(HemlError::Invalid(format!(
                    "set_material: region {r} is out of range (the system has {n} region(s), indices 0..{})",
                    n.saturating_sub(1)
                )));
            }
            if std::mem::replace(&mut seen[*r], true) {
                return Err(HemlError::Invalid(format!("set_material: region {r} is given twice")));
            }
        }
        let cut = self.model.cut.topo.is_some();
        let mut built = Vec::with_capacity(laws.len());
        for (r, material) in laws {
            let tets = self.model.regions[r].field.tet_ids().to_vec();
            let mut field = material
                .force_field(&self.model.mesh, Some(&tets), &self.model.force_options)
                .map_err(|e| HemlError::Invalid(format!("set_material: region {r}, law `{}`: {e}", material.name())))?;
            if cut {
                // the id index later cuts use (as `prepare_cutting` builds it for
                // the first cut; a field that cannot remove tets says so then)
                let _ = field.remove_tets(&[]);
            }
            built.push((r, material, field));
        }
        for (r, material, field) in built {
            let region = &mut self.model.regions[r];
            region.material = material;
            region.field = field;
        }
        self.model.laws_version += 1;
        self.stepping.critical_dt = critical_time_step(self);
        self.model_changed();
        Ok(())
    }
}
