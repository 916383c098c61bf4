//! [`Slider`] supports during a quasi-static solve: imposing their coordinates and
//! taking their reaction out of the residual.

use super::options::Slider;
use crate::system::System;

impl System {
    /// Sets each slider's coordinate to its value and zeroes its velocity component.
    pub(super) fn apply_sliders(&mut self, sliders: &[Slider]) {
        for s in sliders {
            self.state.x[s.node][s.axis] = s.value;
            self.state.v[s.node][s.axis] = 0.0;
        }
        if !sliders.is_empty() {
            self.invalidate();
        }
    }

    /// Records the reaction of each slider and removes its force component.
    pub(super) fn slider_forces(&mut self, sliders: &[Slider], reactions: &mut [f64]) {
        for (s, r) in sliders.iter().zip(reactions) {
            *r = -self.eval.force[s.node][s.axis];
            self.eval.force[s.node][s.axis] = 0.0;
        }
    }
}
