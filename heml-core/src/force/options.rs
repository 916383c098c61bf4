use crate::error::{HemlError, Result};

/// Options shared by every force field.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForceOptions {
    /// Below this J, laws use their second-order Taylor extension in J
    /// (DESIGN §1 "Inversion"). Default 0.4.
    pub j0: f64,
    /// Whether to apply the extension at all. Default true.
    pub inversion_fix: bool,
}

impl Default for ForceOptions {
    fn default() -> Self {
        ForceOptions {
            j0: 0.4,
            inversion_fix: true,
        }
    }
}

impl ForceOptions {
    /// Checks that `j0` lies in (0, 1).
    pub fn validate(&self) -> Result<()> {
        if !(self.j0 > 0.0 && self.j0 < 1.0) {
            return Err(HemlError::Invalid(format!("j0 = {} must lie in (0, 1)", self.j0)));
        }
        Ok(())
    }

    /// Whether a tet at `j` uses the extension, for a law with `fixable` = INVERSION_FIX.
    #[inline(always)]
    pub fn extend(&self, fixable: bool, j: f64) -> bool {
        fixable && self.inversion_fix && j < self.j0
    }
}
