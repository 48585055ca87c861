//! What the processor can do beyond what the build targets. The build is
//! for plain x86-64, so that any such processor runs it; the hot loops
//! that gain from newer instructions are compiled for them as well and
//! run where the processor reports them, asked once.
//!
//! `GCM_ORTHO_KERNELS` (`portable`, `ssse3` or `avx2`) holds the choice
//! lower, to time one against another with one build: every choice gives
//! the same bytes. The run's report names the kernels chosen.

use std::sync::OnceLock;

/// The instruction sets the kernels are compiled for, each needing what
/// the one before it needs and more.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
pub enum Kernels {
    /// What every build has: SSE2 on x86-64.
    Portable,
    /// SSSE3 and SSE4.1 (x86-64 processors since about 2008).
    Ssse3,
    /// AVX2 (since about 2013).
    Avx2,
}

impl Kernels {
    /// Every set, lowest first.
    pub const ALL: [Kernels; 3] = [Kernels::Portable, Kernels::Ssse3, Kernels::Avx2];

    /// The set called `name` (as `GCM_ORTHO_KERNELS` and the report say it).
    pub fn by_name(name: &str) -> Option<Kernels> {
        Self::ALL.into_iter().find(|k| k.name() == name.trim())
    }

    pub fn name(self) -> &'static str {
        match self {
            Kernels::Portable => "portable",
            Kernels::Ssse3 => "ssse3",
            Kernels::Avx2 => "avx2",
        }
    }
}

/// The best kernels this processor runs.
pub fn best() -> Kernels {
    static BEST: OnceLock<Kernels> = OnceLock::new();
    *BEST.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("ssse3") && is_x86_feature_detected!("sse4.1") {
                return Kernels::Avx2;
            }
            if is_x86_feature_detected!("ssse3") && is_x86_feature_detected!("sse4.1") {
                return Kernels::Ssse3;
            }
        }
        Kernels::Portable
    })
}

/// The kernels a run uses: [`best`], or lower where `GCM_ORTHO_KERNELS`
/// says so (a name it does not know is left aside: [`unknown_choice`]).
pub fn chosen() -> Kernels {
    static CHOSEN: OnceLock<Kernels> = OnceLock::new();
    *CHOSEN.get_or_init(|| asked().as_deref().and_then(Kernels::by_name).map_or(best(), |k| k.min(best())))
}

/// What `GCM_ORTHO_KERNELS` asks, if set.
fn asked() -> Option<String> {
    std::env::var("GCM_ORTHO_KERNELS").ok()
}

/// A warning for a run's report where `GCM_ORTHO_KERNELS` names no
/// kernels (the library prints nothing itself).
pub fn unknown_choice() -> Option<String> {
    let names = Kernels::ALL.map(Kernels::name).join(", ");
    asked()
        .filter(|a| Kernels::by_name(a).is_none())
        .map(|a| format!("GCM_ORTHO_KERNELS={a:?} is none of {names}: left aside, the {} kernels run", best().name()))
}

/// A loop to compile for AVX2 too (see [`with_avx2`]): its `run` is
/// `#[inline(always)]` and calls only `#[inline(always)]` code, so that
/// the whole loop is compiled inside the AVX2 function. (A closure would
/// not do: the loop is inlined into it, compiled for the build's target,
/// and the closure called.)
pub trait Loop {
    type Output;
    fn run(self) -> Self::Output;
}

/// `l.run()`, its code compiled for AVX2 where the run's kernels are (a
/// loop the compiler vectorises then takes 32 bytes a step, not 16). Its
/// result must not depend on which way it ran: integer arithmetic, or
/// floating point without fused multiply-adds (which the compiler never
/// forms by itself).
#[inline(always)]
pub fn with_avx2<L: Loop>(l: L) -> L::Output {
    #[cfg(target_arch = "x86_64")]
    if chosen() >= Kernels::Avx2 {
        // SAFETY: `chosen` is at most `best`, which is AVX2 only where the
        // processor reports AVX2.
        return unsafe { avx2(l) };
    }
    l.run()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn avx2<L: Loop>(l: L) -> L::Output {
    l.run()
}
