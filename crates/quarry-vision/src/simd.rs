//! Run-time instruction-set dispatch, shared by the blur ([`crate::blur`]), the watershed
//! ([`crate::watershed`](mod@crate::watershed)) and SIFT ([`crate::sift`]).
//!
//! The hot loops of the crate are plain safe Rust written so that the compiler vectorises them.
//! [`multiversion!`] compiles such a loop (an `#[inline(always)]` body) once more for each listed
//! x86-64 extension (AVX2, or AVX-512F and AVX2) and defines a wrapper that runs the build named
//! by an [`Isa`] level; [`isa`] detects the best level once per process and caches it. Rust never
//! contracts `a * b + c` into a fused multiply-add, and enabling target features does not change
//! the meaning of any other operation, so every build performs the same IEEE operations and the
//! results do not depend on the CPU.
//!
//! This module holds the crate's only `unsafe` code: the calls of the `#[target_feature]`
//! builds inside [`multiversion!`]. They are sound because an [`Isa`] can only be obtained from
//! the detection (its level is private), so a build is only ever run on a CPU that has its
//! features.

use std::sync::OnceLock;

/// The instruction-set levels, in increasing order (each one includes the ones below).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Level {
    /// Baseline of the compilation target (SSE2 on x86-64).
    Base,
    /// AVX2 (detected together with nothing else).
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// AVX-512F, on a CPU that also has AVX2.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

/// An instruction-set level supported by the running CPU. Obtained only from [`isa`] (or, in
/// tests, `Isa::all_supported`), which is what makes the dispatch of [`multiversion!`] sound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Isa(Level);

impl Isa {
    /// The level (for the dispatch in [`multiversion!`]).
    #[inline]
    pub(crate) fn level(self) -> Level {
        self.0
    }

    /// Every level up to the detected one, lowest first (to test that all builds agree).
    #[cfg(test)]
    pub(crate) fn all_supported() -> Vec<Isa> {
        let best = isa().0;
        let mut out = vec![Isa(Level::Base)];
        #[cfg(target_arch = "x86_64")]
        out.extend(
            [Level::Avx2, Level::Avx512]
                .into_iter()
                .filter(|&l| l <= best)
                .map(Isa),
        );
        #[cfg(not(target_arch = "x86_64"))]
        let _ = best;
        out
    }
}

/// The best instruction-set level of this CPU, detected on the first call and cached.
#[inline]
pub(crate) fn isa() -> Isa {
    static DETECTED: OnceLock<Isa> = OnceLock::new();
    *DETECTED.get_or_init(detect)
}

fn detect() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
            return Isa(Level::Avx512);
        }
        if avx2 {
            return Isa(Level::Avx2);
        }
    }
    Isa(Level::Base)
}

/// Defines `$name(level: Isa, args..)`, which runs `$body(args..)` compiled for the best of the
/// listed instruction sets that `level` allows (the baseline build otherwise). The body must be
/// `#[inline(always)]` so that it is compiled inside each `#[target_feature]` wrapper.
///
/// ```text
/// multiversion!(avx512, avx2: fn scan => scan_body(row: &[f32], out: &mut [u8]) -> usize);
/// multiversion!(avx2: fn blur_row<[T: BlurSample]> => blur_row_body(pad: &[T], out: &mut [T]));
/// ```
///
/// Generic parameters go inside `<[ ]>`; the argument types may use them.
macro_rules! multiversion {
    (avx512, avx2: $(#[$m:meta])* $vis:vis fn $name:ident $(<[$($g:tt)*]>)? => $body:ident (
        $($arg:ident : $ty:ty),* $(,)?
    ) $(-> $ret:ty)?) => {
        $(#[$m])*
        $vis fn $name $(<$($g)*>)? (level: $crate::simd::Isa, $($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f")]
            fn avx512 $(<$($g)*>)? ($($arg: $ty),*) $(-> $ret)? {
                $body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2 $(<$($g)*>)? ($($arg: $ty),*) $(-> $ret)? {
                $body($($arg),*)
            }
            match level.level() {
                #[cfg(target_arch = "x86_64")]
                #[allow(unsafe_code)]
                // SAFETY: an `Isa` is at most the detected level, so the CPU has AVX-512F.
                $crate::simd::Level::Avx512 => unsafe { avx512($($arg),*) },
                #[cfg(target_arch = "x86_64")]
                #[allow(unsafe_code)]
                // SAFETY: an `Isa` is at most the detected level, so the CPU has AVX2.
                $crate::simd::Level::Avx2 => unsafe { avx2($($arg),*) },
                $crate::simd::Level::Base => $body($($arg),*),
            }
        }
    };
    (avx2: $(#[$m:meta])* $vis:vis fn $name:ident $(<[$($g:tt)*]>)? => $body:ident (
        $($arg:ident : $ty:ty),* $(,)?
    ) $(-> $ret:ty)?) => {
        $(#[$m])*
        $vis fn $name $(<$($g)*>)? (level: $crate::simd::Isa, $($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2 $(<$($g)*>)? ($($arg: $ty),*) $(-> $ret)? {
                $body($($arg),*)
            }
            match level.level() {
                #[cfg(target_arch = "x86_64")]
                #[allow(unsafe_code)]
                // SAFETY: an `Isa` is at most the detected level, and the AVX-512 level is only
                // detected on CPUs that also have AVX2.
                $crate::simd::Level::Avx512 | $crate::simd::Level::Avx2 => unsafe {
                    avx2($($arg),*)
                },
                $crate::simd::Level::Base => $body($($arg),*),
            }
        }
    };
}
pub(crate) use multiversion;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detection_is_cached_and_ordered() {
        assert_eq!(isa(), isa());
        let all = Isa::all_supported();
        assert_eq!(all[0].level(), Level::Base);
        assert_eq!(all.last().map(|l| l.level()), Some(isa().level()));
        assert!(all.windows(2).all(|w| w[0].level() < w[1].level()));
    }
}
