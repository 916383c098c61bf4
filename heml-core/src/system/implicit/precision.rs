//! The floating-point precision of the sparse Cholesky factor ([`FactorPrecision`]).
//!
//! The factor is only ever a preconditioner of the Newton iterations: every
//! residual is the exact one, evaluated in f64 from the forces, and the chord
//! iterations on a kept factor already correct whatever the factor misses (a
//! factor several steps old misses ~10⁻¹ of each correction). A factor computed in
//! f32 misses ~κ·10⁻⁷ of a correction (κ the condition number of the system
//! matrix), which those iterations correct the same way: iterative refinement
//! with a low-precision factor, here for free. In exchange a factorisation and a
//! pair of triangular solves move half the bytes and run twice as many lanes per
//! vector instruction: on gen_kidney_20k's system (nested dissection, 3.9·10⁶
//! factor nonzeros) f32 factors ~2× faster and solves ~1.8× faster
//! (`docs/journal/implicit-steps.md`, session 18).
//!
//! The time-stepping matrix M/h² + K is well conditioned (its smallest eigenvalue
//! is at least the smallest nodal mass over h²), which is where f32 is safe; a
//! static solve's K alone may not be, so [`FactorPrecision::Auto`] keeps f64
//! there. A matrix whose f32 factorisation meets a non-positive pivot (an entry
//! that underflows or a system too ill-conditioned for f32) is factored again in
//! f64, so f32 never makes a solve fail that f64 would do.

/// The precision of [`super::LinearSolver::Cholesky`]'s factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FactorPrecision {
    /// f32 for time steps (a mass term on the diagonal) from [`AUTO_SINGLE`] free
    /// coordinates on, f64 otherwise (the default): tiny systems and static solves
    /// keep the factor, and the bits, they had before session 18.
    #[default]
    Auto,
    /// Always f64.
    #[serde(rename = "f64")]
    Double,
    /// f32 (falling back to f64 for a factorisation that meets a non-positive pivot
    /// in f32).
    #[serde(rename = "f32")]
    Single,
}

/// Free coordinates from which [`FactorPrecision::Auto`] factors time steps in f32.
/// Session 18 took nested dissection's threshold (3000), the liver's gain (513
/// unknowns) being within that day's noise; session 35 measured it again in
/// alternated pairs of long runs (`heml bench --implicit --factor-precision
/// f64,f32`, same binary): f32 made the liver's run 6–12 % faster in all eight
/// pairs (four runs at 1 and 2 threads; factorisations −19 to −30 %, solves −7 to
/// −24 %, the same Newton iterations), and gen_kidney_2k's and gen_blob_2k's (~1400
/// unknowns) 10–23 % in six of eight (the other two were slower in their unchanged
/// force phase too: the machine).
/// Below a few hundred unknowns a factorisation and a solve take microseconds and
/// nothing is left to gain: such systems keep the f64 factor and their bits.
pub const AUTO_SINGLE: usize = 256;

impl FactorPrecision {
    /// Whether a system of `unknowns` free coordinates, with a mass term when
    /// `dynamic`, is factored in f32.
    pub(in crate::system) fn single(self, unknowns: usize, dynamic: bool) -> bool {
        match self {
            FactorPrecision::Double => false,
            FactorPrecision::Single => true,
            FactorPrecision::Auto => dynamic && unknowns >= AUTO_SINGLE,
        }
    }

    /// The scene-file name of the precision.
    ///
    /// ```
    /// use heml_core::system::FactorPrecision;
    /// assert_eq!(FactorPrecision::Single.name(), "f32");
    /// assert_eq!("f32".parse::<FactorPrecision>().unwrap(), FactorPrecision::Single);
    /// ```
    pub fn name(self) -> &'static str {
        match self {
            FactorPrecision::Auto => "auto",
            FactorPrecision::Double => "f64",
            FactorPrecision::Single => "f32",
        }
    }
}

impl std::str::FromStr for FactorPrecision {
    type Err = crate::error::HemlError;

    /// The precision named as in scene files (`auto`, `f64`, `f32`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        [FactorPrecision::Auto, FactorPrecision::Double, FactorPrecision::Single]
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                crate::error::HemlError::Invalid(format!("factor_precision must be 'auto', 'f64' or 'f32', got {s:?}"))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Auto takes f32 only for time steps at or above the threshold; the forced
    /// settings ignore both.
    #[test]
    fn auto_takes_single_only_for_large_time_steps() {
        let p = FactorPrecision::Auto;
        assert!(p.single(AUTO_SINGLE, true));
        assert!(!p.single(AUTO_SINGLE - 1, true));
        assert!(!p.single(AUTO_SINGLE * 10, false));
        assert!(FactorPrecision::Single.single(3, false));
        assert!(!FactorPrecision::Double.single(AUTO_SINGLE * 10, true));
    }

    /// Names round-trip; a misspelt one is an error that lists the choices.
    #[test]
    fn names_parse_back() {
        for p in [FactorPrecision::Auto, FactorPrecision::Double, FactorPrecision::Single] {
            assert_eq!(p.name().parse::<FactorPrecision>().unwrap(), p);
        }
        let e = "double".parse::<FactorPrecision>().unwrap_err().to_string();
        assert!(e.contains("'f64'") && e.contains("\"double\""), "{e}");
    }
}
