//! Setting a system's clock, for programs that carry a state over to a rebuilt
//! system (the live viewer changes a material parameter by rebuilding the system
//! from its scene and copying positions and velocities): prescribed motions and
//! ramps must continue from the old time, not restart at zero.

use super::System;
use crate::error::{HemlError, Result};

impl System {
    /// Sets the simulated time and the step count, then imposes the constraints at
    /// that time. Refused inside a step, or for a time that is not finite and ≥ 0.
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::system::System;
    /// # use heml_core::{law::*, material::Link};
    /// # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
    /// # impl MaterialInfo for Spring {
    /// #     const NAME: &'static str = "doc_clock_spring"; const PARAMS: &'static [ParamInfo] = &[];
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
    /// let mesh = box_mesh([0.1, 0.1, 0.1], [1, 1, 1], HexSplit::Six)?;
    /// let mut sys = System::builder(mesh).material_law(Box::new(Link(Spring { k: 1.0 }))).build()?;
    /// sys.set_clock(1.5, 300)?;
    /// assert_eq!((sys.time(), sys.step_count()), (1.5, 300));
    /// assert!(sys.set_clock(f64::NAN, 0).is_err());
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn set_clock(&mut self, time: f64, steps: u64) -> Result<()> {
        if self.state.in_step.is_some() {
            return Err(HemlError::Invalid("set_clock: a step is in progress".into()));
        }
        if !(time.is_finite() && time >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "set_clock: time {time} must be finite and ≥ 0"
            )));
        }
        self.state.t = time;
        self.state.step = steps;
        self.invalidate();
        self.apply_constraints(time);
        Ok(())
    }
}
