//! Runtime CPU dispatch. Hot kernels are plain Rust written so LLVM can vectorize them; this macro
//! compiles such a kernel a second time with AVX2 enabled and picks that copy when the CPU has it,
//! so one portable binary still gets 256-bit vectors. Everything the kernel calls must be
//! `#[inline(always)]` to be compiled inside the AVX2 copy.

macro_rules! dispatch_avx2 {
    ($(#[$m:meta])* $vis:vis fn $name:ident $(<$($lt:lifetime),*>)? ($($arg:ident : $ty:ty),* $(,)?) => $imp:path) => {
        $(#[$m])*
        $vis fn $name $(<$($lt),*>)? ($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                $(#[$m])*
                #[target_feature(enable = "avx2,popcnt,bmi1,bmi2")]
                unsafe fn avx2 $(<$($lt),*>)? ($($arg: $ty),*) {
                    $imp($($arg),*)
                }
                if $crate::simd::has_avx2()
                    && std::arch::is_x86_feature_detected!("popcnt")
                {
                    // SAFETY: the CPU supports every feature enabled on `avx2`.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $imp($($arg),*)
        }
    };
}
pub(crate) use dispatch_avx2;

/// Unit tests set this to run the portable paths on an AVX2 machine and compare the two.
#[cfg(test)]
pub(crate) static FORCE_SCALAR: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);

/// Unit tests set this to run block matching's previous row step, the reference for the others.
#[cfg(test)]
pub(crate) static REFERENCE_ROWS: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);

/// Cached runtime check (std caches the CPUID result; this is one relaxed load).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn has_avx2() -> bool {
    #[cfg(test)]
    if FORCE_SCALAR.load(std::sync::atomic::Ordering::Relaxed) {
        return false;
    }
    std::arch::is_x86_feature_detected!("avx2")
}
