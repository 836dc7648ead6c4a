//! Seeded, reproducible randomness.
//!
//! Every random draw in quarry takes a generator passed in by the caller. [`seeded`] makes one
//! from a seed; [`stream`] derives independent per-particle / per-target streams from a seed and
//! a list of ids, so that results do not depend on the order (or thread) in which streams are
//! used.
//!
//! ```
//! use quarry_core::rng::{seeded, stream};
//! use rand_core::RngCore;
//! let mut a = seeded(7);
//! let mut b = seeded(7);
//! assert_eq!(a.next_u64(), b.next_u64());
//! assert_ne!(stream(7, &[1]).next_u64(), stream(7, &[2]).next_u64());
//! ```

pub use rand_core::RngCore;
use rand_core::SeedableRng;

/// The generator quarry uses: xoshiro256++ (fast, 256-bit state, passes BigCrush).
pub type SeededRng = rand_xoshiro::Xoshiro256PlusPlus;

/// A generator from a 64-bit seed.
pub fn seeded(seed: u64) -> SeededRng {
    SeededRng::seed_from_u64(seed)
}

/// SplitMix64 finaliser: a bijective 64-bit mixer.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An independent generator for the stream identified by `(seed, ids...)`.
pub fn stream(seed: u64, ids: &[u64]) -> SeededRng {
    let mut h = mix(seed);
    for &id in ids {
        h = mix(h ^ mix(id.wrapping_add(0x632B_E59B_D9B4_E019)));
    }
    SeededRng::seed_from_u64(h)
}
