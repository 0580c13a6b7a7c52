//! Coarse emptiness for the ray marcher: a bitmap over super-blocks of `4 × 4 × 4` blocks
//! (32 voxels on a side), one bit per hashed super-block, set for every super-block holding an
//! allocated block. A clear bit proves the super-block empty, so a ray in it jumps to its exit
//! in one step instead of crossing up to 4 unallocated blocks one hash lookup at a time (on a
//! real recording most steps of a ray are such jumps through the empty space between the
//! camera and the surface). A set bit may be a hash collision and only means "step block by
//! block", so the bitmap never changes what a ray can hit. Rebuilt for every raycast from the
//! block keys, in parallel; its memory is reused across frames.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::error::{Result, TsdfError};
use crate::hash::{pack, unpack};
use crate::volume::TsdfVolume;

/// log2 of the blocks per super-block side.
pub(super) const SUPER_SHIFT: i32 = 2;

/// Bits in the map: 2^20 (128 KiB), so that a volume of a million blocks (at most a million
/// super-blocks, usually tens of times fewer) still leaves most bits of empty space clear.
const MAP_BITS: u32 = 20;

/// The super-block bitmap (scratch space; cloning gives an empty one, which `fill` sizes).
#[derive(Debug, Default)]
pub(super) struct Occupancy(Vec<AtomicU64>);

impl Clone for Occupancy {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// The bit of super-block `sb`: Fibonacci hashing of its packed coordinates.
#[inline(always)]
fn bit(sb: [i32; 3]) -> Option<usize> {
    let key = pack(sb)?;
    Some((key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - MAP_BITS)) as usize)
}

impl Occupancy {
    /// Sets the bits of the super-blocks of `vol`'s allocated blocks (all others cleared).
    pub(super) fn fill(&mut self, vol: &TsdfVolume) -> Result<()> {
        let words = (1usize << MAP_BITS) / 64;
        if self.0.len() != words {
            self.0.clear();
            self.0
                .try_reserve_exact(words)
                .map_err(|_| TsdfError::OutOfMemory("raycast occupancy map"))?;
            self.0.resize_with(words, || AtomicU64::new(0));
        }
        for w in &mut self.0 {
            *w.get_mut() = 0;
        }
        let map: &[AtomicU64] = &self.0;
        vol.keys().par_chunks(4096).for_each(|keys| {
            let mut last = None;
            for &key in keys {
                let sb = unpack(key).map(|c| c >> SUPER_SHIFT);
                // Keys of neighbouring blocks often share a super-block: skip repeats.
                if last == Some(sb) {
                    continue;
                }
                last = Some(sb);
                if let Some(i) = bit(sb) {
                    map[i / 64].fetch_or(1 << (i % 64), Ordering::Relaxed);
                }
            }
        });
        Ok(())
    }

    /// Whether super-block `sb` may hold an allocated block (`false`: certainly not).
    #[inline]
    pub(super) fn maybe_occupied(&self, sb: [i32; 3]) -> bool {
        match bit(sb) {
            Some(i) => match self.0.get(i / 64) {
                Some(w) => w.load(Ordering::Relaxed) & (1 << (i % 64)) != 0,
                None => true,
            },
            None => true,
        }
    }
}
