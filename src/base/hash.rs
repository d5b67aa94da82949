//! The one stable hash: FNV-1a, fixed forever, never `std`'s `Hasher` (whose output may
//! change between releases). Seeds ([`super::seed`]) and the keys of stored trials
//! (`pipeline::run::trial_key`) are built on it, so a seed or a key means the same bytes everywhere.

pub(crate) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a of `bytes` continued from state `h`.
pub(crate) fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(FNV_PRIME);
    }
    h
}

/// A 128-bit FNV-1a hash (two 64-bit lanes with different offsets) of `parts`, each
/// terminated by 0xFF, as hex. Fixed forever: keys name stored trials.
pub fn stable_hash(parts: &[&[u8]]) -> String {
    let mut lanes = [FNV_OFFSET, 0x6c62_272e_07bb_0142u64];
    for part in parts {
        for &b in part.iter().chain(&[0xffu8]) {
            for (k, h) in lanes.iter_mut().enumerate() {
                *h ^= u64::from(b) ^ ((k as u64) << 8);
                *h = h.wrapping_mul(FNV_PRIME);
            }
        }
    }
    format!("{:016x}{:016x}", lanes[0], lanes[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_is_frozen_and_separates_parts() {
        // Keys name stored trials: a change here orphans every stored result.
        assert_eq!(stable_hash(&[b"a", b"b"]), stable_hash(&[b"a", b"b"]));
        assert_ne!(stable_hash(&[b"ab", b""]), stable_hash(&[b"a", b"b"]));
        assert_eq!(stable_hash(&[b"optbench"]), GOLDEN);
    }

    // Cross-checked with an independent Python implementation of the same loop.
    const GOLDEN: &str = "6ca367c9fd1f48cd7a7f76c0cf8266f8";
}
