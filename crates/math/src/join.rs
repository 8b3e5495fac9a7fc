//! Fork-join without threads: a kernel that can split its work in two
//! halves hands both to a [`Join`], which runs them one after the other
//! ([`Serial`]) or, given by a caller that owns threads (the engine's
//! stages, on a rayon pool), at once. This crate starts no thread; the
//! halves write disjoint parts of their outputs, so the result is the same
//! bits either way.

/// Runs two pieces of work, in any order or at once, and returns when
/// both are done.
pub trait Join: Sync {
    fn join(&self, a: &mut (dyn FnMut() + Send), b: &mut (dyn FnMut() + Send));
}

/// One after the other, on the caller's thread.
#[derive(Clone, Copy, Debug, Default)]
pub struct Serial;

impl Join for Serial {
    fn join(&self, a: &mut (dyn FnMut() + Send), b: &mut (dyn FnMut() + Send)) {
        a();
        b();
    }
}

/// The widest vectors the running CPU has. Code that runs through
/// [`Simd::run`] is compiled for them: a kernel is written once, as plain
/// loops, and vectorised three ways (SSE2, AVX2, AVX-512) with the same
/// IEEE operations in the same order (no FMA contraction), so every path
/// gives the same bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Simd {
    Sse2,
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx2,
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx512,
}

impl Simd {
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            let avx512 = std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512dq");
            if avx2 && avx512 {
                return Simd::Avx512;
            }
            if avx2 {
                return Simd::Avx2;
            }
        }
        Simd::Sse2
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Simd::Sse2 => "sse2",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        }
    }
}

/// Defines `fn NAME(simd: Simd, ARGS) -> RET` that runs BODY compiled for
/// `simd`'s vectors: BODY is written once, as plain loops, and compiled
/// three times (SSE2, AVX2, AVX-512), the copy the CPU can run chosen per
/// call. (A closure does not take its caller's target features; a
/// function with them does.)
macro_rules! simd_fn {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($a:ident: $t:ty),* $(,)?) $(-> $r:ty)? $body:block) => {
        $(#[$m])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name(simd: $crate::join::Simd, $($a: $t),*) $(-> $r)? {
            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            fn body($($a: $t),*) $(-> $r)? $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,fma")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx512($($a: $t),*) $(-> $r)? {
                body($($a),*)
            }
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx2($($a: $t),*) $(-> $r)? {
                body($($a),*)
            }
            match simd {
                // SAFETY: a `Simd` other than `Sse2` comes only from
                // `Simd::detect`, which saw the running CPU report these
                // features.
                #[cfg(target_arch = "x86_64")]
                $crate::join::Simd::Avx512 => unsafe { avx512($($a),*) },
                #[cfg(target_arch = "x86_64")]
                $crate::join::Simd::Avx2 => unsafe { avx2($($a),*) },
                _ => body($($a),*),
            }
        }
    };
}
pub(crate) use simd_fn;

/// A [`Join`] and the vectors its halves are compiled for.
#[derive(Clone, Copy)]
pub(crate) struct Par<'a> {
    pub(crate) j: &'a dyn Join,
    pub(crate) simd: Simd,
}

/// `a` and `b` through `par`'s join (each calls kernels made with
/// [`simd_fn`], given `par.simd`) when the work was `split`; in turn on
/// this thread when it was not (one of the two has nothing to do, and a
/// hand-over costs more than nothing).
#[inline(always)]
pub(crate) fn both(
    par: Par<'_>,
    split: bool,
    mut a: impl FnMut() + Send,
    mut b: impl FnMut() + Send,
) {
    if split {
        par.j.join(&mut a, &mut b);
    } else {
        a();
        b();
    }
}
