//! Which instruction set the block driver runs with, and the proof that the CPU has
//! it: the AVX2 and AVX-512 paths take a token that only run-time detection makes.

thread_local! {
    static FORCED_LEVEL: std::cell::Cell<Option<SimdLevel>> = const { std::cell::Cell::new(None) };
}

/// The instruction set the block driver is compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimdLevel {
    /// x86-64 AVX-512 (F, DQ, VL) with AVX2 and FMA. Compiled in only with the
    /// `avx512` cargo feature (of heml-core, or of the `heml` facade), and then
    /// only picked on request (`HEML_SIMD=avx512`): on the machine the kernels were
    /// tuned on it measured 1.7–2× slower than AVX2, and its block drivers, one more
    /// per force field of every law, took ~30 % of each law's release build
    /// (heml-materials 214 s → 152 s without them). Without the feature the CPU is
    /// treated as not having it ([`Self::available`] does not list it).
    Avx512,
    /// x86-64 AVX2 with FMA.
    Avx2,
    /// The target's baseline (SSE2 on x86-64).
    Baseline,
}

impl SimdLevel {
    /// The best level this CPU supports (detected once, at run time).
    pub fn detect() -> SimdLevel {
        static LEVEL: std::sync::OnceLock<SimdLevel> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(|| {
            // AVX-512 is opt-in (HEML_SIMD=avx512): on the AMD EPYC (Zen 4) machine
            // the kernels were tuned on, LLVM's AVX-512 code for them (gathers,
            // scatters, mask moves) measured slower than the AVX2 code.
            if let Ok(v) = std::env::var("HEML_SIMD") {
                match v.as_str() {
                    "baseline" => return SimdLevel::Baseline,
                    "avx2" if has_avx2() => return SimdLevel::Avx2,
                    "avx512" if has_avx512() => return SimdLevel::Avx512,
                    "avx512" if !cfg!(feature = "avx512") => log::warn!(
                        "HEML_SIMD=avx512: this build has no AVX-512 kernels (heml-core's \
                         `avx512` feature); using the default"
                    ),
                    _ => {}
                }
            }
            if has_avx2() {
                SimdLevel::Avx2
            } else {
                SimdLevel::Baseline
            }
        })
    }

    /// The levels this CPU can run, best first (AVX-512 included when supported,
    /// although [`Self::detect`] only picks it on request).
    pub fn available() -> Vec<SimdLevel> {
        let mut v = Vec::new();
        if has_avx512() {
            v.push(SimdLevel::Avx512);
        }
        if has_avx2() {
            v.push(SimdLevel::Avx2);
        }
        v.push(SimdLevel::Baseline);
        v
    }

    /// Runs `f` with the batched and parallel kernels started from this thread
    /// using this level instead of the detected one: for tests and benchmarks that
    /// compare the instruction sets. `None` when the CPU cannot run it.
    pub fn run_with<R>(self, f: impl FnOnce() -> R) -> Option<R> {
        if !Self::available().contains(&self) {
            return None;
        }
        let previous = FORCED_LEVEL.with(|c| c.replace(Some(self)));
        // restored even if `f` panics
        struct Restore(Option<SimdLevel>);
        impl Drop for Restore {
            fn drop(&mut self) {
                FORCED_LEVEL.with(|c| c.set(self.0));
            }
        }
        let _restore = Restore(previous);
        Some(f())
    }

    /// The level the kernels use on this thread: forced by [`Self::run_with`], or
    /// detected.
    fn current() -> SimdLevel {
        FORCED_LEVEL.with(|c| c.get()).unwrap_or_else(SimdLevel::detect)
    }

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Avx2 => "avx2+fma",
            SimdLevel::Baseline => "baseline",
        }
    }
}

#[cfg(all(target_arch = "x86_64", feature = "avx512"))]
fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && has_avx2()
}
#[cfg(target_arch = "x86_64")]
fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}
#[cfg(not(all(target_arch = "x86_64", feature = "avx512")))]
fn has_avx512() -> bool {
    false
}
#[cfg(not(target_arch = "x86_64"))]
fn has_avx2() -> bool {
    false
}

/// Proof that this CPU runs AVX2 and FMA. The field is private and the only
/// constructors are [`Avx2Token::detect`] and [`Avx512Token::avx2`], so holding one
/// means run-time detection saw both features: what the AVX2 lane I/O and the block
/// driver compiled with `avx2,fma` need to be sound.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx2Token(());

impl Avx2Token {
    /// A token when the CPU reports avx2 and fma.
    pub(crate) fn detect() -> Option<Avx2Token> {
        has_avx2().then_some(Avx2Token(()))
    }
}

/// Proof that this CPU runs AVX-512 (F, DQ, VL), AVX2 and FMA; made only by
/// [`Avx512Token::detect`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx512Token(());

impl Avx512Token {
    /// A token when the CPU reports avx512f, avx512dq, avx512vl, avx2 and fma.
    pub(crate) fn detect() -> Option<Avx512Token> {
        has_avx512().then_some(Avx512Token(()))
    }

    /// AVX-512 detection includes AVX2 and FMA (`has_avx512` requires them).
    pub(crate) fn avx2(self) -> Avx2Token {
        Avx2Token(())
    }
}

/// The instruction set a block runs with, carrying its proof.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Isa {
    /// The driver compiled with AVX-512, AVX2 and FMA enabled.
    Avx512(Avx512Token),
    /// The driver compiled with AVX2 and FMA enabled.
    Avx2(Avx2Token),
    /// The driver compiled for the baseline target.
    Portable,
}

impl Isa {
    /// The AVX2 proof this instruction set carries (AVX-512 includes AVX2), for code
    /// that has only an AVX2 variant.
    pub(crate) fn avx2(self) -> Option<Avx2Token> {
        match self {
            Isa::Avx512(t) => Some(t.avx2()),
            Isa::Avx2(t) => Some(t),
            Isa::Portable => None,
        }
    }

    /// The level of [`SimdLevel::current`], proven on this CPU. `current` only
    /// returns levels the CPU supports, so the fall-backs are never taken; they keep
    /// a missing feature from ever reaching an unsafe path.
    pub(crate) fn current() -> Isa {
        match SimdLevel::current() {
            SimdLevel::Avx512 => Avx512Token::detect().map_or(Isa::Portable, Isa::Avx512),
            SimdLevel::Avx2 => Avx2Token::detect().map_or(Isa::Portable, Isa::Avx2),
            SimdLevel::Baseline => Isa::Portable,
        }
    }
}
