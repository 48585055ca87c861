//! The span loops' kernel chosen at run time ([`crate::processor`]): the
//! one place the kernels compiled for SSSE3 + SSE4.1 and for AVX2 are
//! called.

use super::{span_inside_portable, Fixed};
use crate::processor::{best, Kernels};

/// [`super::span_inside_any`] by `kernels`, or by [`best`] where the
/// processor lacks what they need.
#[inline(always)]
pub fn span_inside<const B: usize>(kernels: Kernels, bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    match kernels.min(best()) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `best` is AVX2 only where the processor reports AVX2.
        Kernels::Avx2 => unsafe { super::x86::span_inside_avx2::<B>(bytes, row, origin, f, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `best` is SSSE3 or above only where the processor
        // reports SSSE3 and SSE4.1.
        Kernels::Ssse3 => unsafe { super::x86::span_inside_ssse3::<B>(bytes, row, origin, f, out) },
        _ => span_inside_portable::<B>(bytes, row, origin, f, out),
    }
}
