//! The instruction sets the workspace's hot loops are compiled for, and running a loop compiled
//! for one of them.
//!
//! The workspace is built for baseline x86-64 (SSE2), so that one binary runs on every x86-64
//! CPU. Loops that pay for wider vectors are compiled a second and third time for AVX2 + FMA
//! and AVX-512 and chosen at run time ([`Isa::detect`]); a caller can ask for a narrower set
//! (benchmarks compare them on one machine, tests check that they agree).
//!
//! [`Isa::run`] runs a [`IsaKernel`] compiled for an instruction set through the `pulp`
//! crate's target-feature trampolines (the workspace itself has no `unsafe` for it). Such a
//! kernel is plain Rust that the compiler vectorises; it contracts no multiply–add into a
//! fused one (Rust never does without being asked), so every instruction set gives
//! bit-identical results wherever the kernel's arithmetic is elementwise.
//!
//! ```
//! use sl_core::{Isa, IsaKernel};
//!
//! struct Scale<'a>(&'a mut [f32], f32);
//! impl IsaKernel for Scale<'_> {
//!     type Output = ();
//!     #[inline(always)]
//!     fn run(self) {
//!         for v in self.0.iter_mut() {
//!             *v *= self.1;
//!         }
//!     }
//! }
//!
//! let mut v = vec![1.0f32; 100];
//! Isa::detect().run(Scale(&mut v, 3.0));
//! Isa::Portable.run(Scale(&mut v, 0.5));
//! assert!(v.iter().all(|&x| x == 1.5));
//! ```

/// An instruction set a hot loop is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// Portable code (whatever the compile target allows; SSE2 on a default x86-64 build).
    Portable,
    /// AVX2 + FMA (256-bit vectors).
    Avx2,
    /// AVX-512F + DQ (512-bit vectors; the compiler-vectorised loops also use BW, CD and VL,
    /// which every CPU with F and DQ has).
    Avx512,
}

impl Isa {
    /// Every instruction set, narrowest first.
    pub const ALL: [Isa; 3] = [Isa::Portable, Isa::Avx2, Isa::Avx512];

    /// The widest instruction set this CPU supports.
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Isa::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// Whether this CPU can run `self`.
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Avx2 => matches!(Isa::detect(), Isa::Avx2 | Isa::Avx512),
            Isa::Avx512 => Isa::detect() == Isa::Avx512,
        }
    }

    /// Short name (`portable`, `avx2`, `avx512`).
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// The instruction set named `name` ([`Isa::name`]), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Isa::ALL.into_iter().find(|i| i.name() == name)
    }

    /// The instruction set [`Isa::run`] runs a kernel with when asked for `self`: `self`, or
    /// the widest narrower set this CPU supports.
    pub fn effective(self) -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if self == Isa::Avx512 && pulp::x86::V4::is_available() {
                return Isa::Avx512;
            }
            if self != Isa::Portable && pulp::x86::V3::is_available() {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// Runs `kernel` compiled for `self`, or for the widest narrower set this CPU supports
    /// (portable code at worst, see [`Isa::effective`]): asking for an instruction set never
    /// fails.
    #[inline(always)]
    pub fn run<K: IsaKernel>(self, kernel: K) -> K::Output {
        #[cfg(target_arch = "x86_64")]
        {
            if self == Isa::Avx512
                && let Some(simd) = pulp::x86::V4::try_new()
            {
                return simd.vectorize(Trampoline(kernel));
            }
            if self != Isa::Portable
                && let Some(simd) = pulp::x86::V3::try_new()
            {
                return simd.vectorize(Trampoline(kernel));
            }
        }
        kernel.run()
    }
}

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Bytes of a cache line on the CPUs the workspace targets (x86-64).
pub const CACHE_LINE_BYTES: usize = 64;

/// Asks the CPU to start loading every cache line of `data` into its caches, and returns at
/// once. For a loop about to read memory whose address the hardware prefetcher cannot guess,
/// such as the next of many scattered 4 KB voxel blocks (a prefetcher stops at page borders):
/// issued one block ahead, the loads overlap the current block's arithmetic. A hint only: it
/// changes no result, never faults, and does nothing on other architectures. Through `pulp`'s
/// safe wrapper of `_mm_prefetch` (SSE, part of baseline x86-64).
#[inline(always)]
pub fn prefetch<T>(data: &[T]) {
    #[cfg(target_arch = "x86_64")]
    if let Some(sse) = pulp::core_arch::x86::Sse::try_new() {
        let first = data.as_ptr().cast::<i8>();
        for offset in (0..std::mem::size_of_val(data)).step_by(CACHE_LINE_BYTES) {
            sse._mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(first.wrapping_add(offset));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = data;
}

/// A loop to be compiled once per instruction set and run by [`Isa::run`].
///
/// `run` must be `#[inline(always)]`, and so must everything hot that it calls: only code
/// inlined into the trampoline is compiled with the trampoline's instruction set.
pub trait IsaKernel {
    /// What the loop returns.
    type Output;
    /// The loop.
    fn run(self) -> Self::Output;
}

/// Adapts an [`IsaKernel`] to `pulp`'s trampoline.
struct Trampoline<K>(K);

impl<K: IsaKernel> pulp::NullaryFnOnce for Trampoline<K> {
    type Output = K::Output;
    #[inline(always)]
    fn call(self) -> K::Output {
        self.0.run()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Sum<'a>(&'a [f32]);
    impl IsaKernel for Sum<'_> {
        type Output = f32;
        #[inline(always)]
        fn run(self) -> f32 {
            self.0.iter().map(|v| v * 1.5 + 0.25).sum()
        }
    }

    #[test]
    fn every_instruction_set_runs_and_agrees() {
        let v: Vec<f32> = (0..1000).map(|i| (i as f32).sqrt()).collect();
        let base = Isa::Portable.run(Sum(&v));
        for isa in Isa::ALL {
            assert_eq!(isa.run(Sum(&v)).to_bits(), base.to_bits(), "{isa}");
        }
    }

    #[test]
    fn prefetch_is_only_a_hint() {
        let v: Vec<f32> = (0..1000).map(|i| i as f32).collect();
        prefetch(&v);
        prefetch(&v[999..]);
        prefetch::<f32>(&[]);
        assert_eq!(v.iter().sum::<f32>(), 499_500.0);
    }

    #[test]
    fn names_round_trip() {
        for isa in Isa::ALL {
            assert_eq!(Isa::from_name(isa.name()), Some(isa));
        }
        assert_eq!(Isa::from_name("sse9"), None);
        assert!(Isa::Portable.is_supported());
        assert!(Isa::detect().is_supported());
        assert_eq!(Isa::Portable.effective(), Isa::Portable);
        for isa in Isa::ALL {
            let e = isa.effective();
            assert!(
                e.is_supported() && e as u8 <= isa as u8,
                "{isa} runs as {e}"
            );
        }
    }
}
