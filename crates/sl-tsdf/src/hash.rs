//! A small, fast hasher for the packed 64-bit block keys (the hash map sits on the hot path of
//! block allocation; SipHash would cost more than the rest of the lookup).

use std::hash::{BuildHasherDefault, Hasher};

/// Hashes a `u64` with the 64-bit finaliser of MurmurHash3 (two multiplications): every input
/// bit affects every output bit, so packed `(x, y, z)` keys spread over all buckets.
#[derive(Debug, Default, Clone, Copy)]
pub struct BlockHasher(u64);

impl Hasher for BlockHasher {
    #[inline]
    fn finish(&self) -> u64 {
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^= h >> 33;
        h
    }

    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.0 ^= v;
    }
}

/// `BuildHasher` of [`BlockHasher`].
pub type BuildBlockHasher = BuildHasherDefault<BlockHasher>;

/// Hash map from packed block keys.
pub type BlockMap<V> = std::collections::HashMap<u64, V, BuildBlockHasher>;

const BITS: u32 = 21;
const BIAS: i32 = 1 << (BITS - 1);
const MASK: u64 = (1 << BITS) - 1;

/// Largest block coordinate magnitude that can be packed.
pub const MAX_BLOCK_COORD: i32 = BIAS - 1;

/// Packs block coordinates (each in `[-2^20, 2^20)`) into one `u64`; `None` out of range.
#[inline]
pub fn pack(b: [i32; 3]) -> Option<u64> {
    let mut k = 0u64;
    for (i, &c) in b.iter().enumerate() {
        if !(-BIAS..BIAS).contains(&c) {
            return None;
        }
        k |= ((c + BIAS) as u64) << (BITS * i as u32);
    }
    Some(k)
}

/// Inverse of [`pack`].
#[inline]
pub fn unpack(k: u64) -> [i32; 3] {
    [0, 1, 2].map(|i| ((k >> (BITS * i)) & MASK) as i32 - BIAS)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use std::hash::BuildHasher;

    #[test]
    fn pack_round_trip() {
        for b in [[0, 0, 0], [-1, 2, -3], [MAX_BLOCK_COORD, -BIAS, 17]] {
            assert_eq!(unpack(pack(b).unwrap()), b);
        }
        assert!(pack([BIAS, 0, 0]).is_none());
    }

    #[test]
    fn hash_spreads_low_bits() {
        let bh = BuildBlockHasher::default();
        // Keys differing only in z must land in different low-bit buckets.
        let mut buckets = std::collections::HashSet::new();
        for z in 0..64 {
            buckets.insert(bh.hash_one(pack([3, 4, z]).unwrap()) & 63);
        }
        assert!(buckets.len() > 30, "{}", buckets.len());
    }
}
