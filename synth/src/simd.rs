//! Hot loops compiled twice — portably, and for AVX2 on x86-64 CPUs that have it — and chosen
//! at run time, so one binary runs everywhere and uses the wide vector unit where there is one.
//! Only integer code goes through here: both builds compute the same values, so the choice
//! never changes a pixel (native and wasm32 alike).

/// Defines `fn NAME(args) -> R { body }` whose body is compiled twice, portably and for AVX2,
/// the AVX2 build called when the CPU has it. What the body calls is compiled for AVX2 only
/// where it is inlined: mark the hot path `#[inline(always)]`. `NAME_portable` is the
/// portable build, for tests that hold the two to each other.
macro_rules! widest {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2($($arg: $ty),*) $(-> $ret)? {
                portable($($arg),*)
            }
            #[inline(always)]
            fn portable($($arg: $ty),*) $(-> $ret)? $body

            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has just been found to support AVX2.
                #[allow(unsafe_code)]
                return unsafe { avx2($($arg),*) };
            }
            portable($($arg),*)
        }
    };
}
pub(crate) use widest;
