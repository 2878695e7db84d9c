//! Seeds derived by hashing: every random stream of a driver (an ensemble's samples, the
//! GA's generations, the kernel's speed samples, the subgrid's replica boxes, the live
//! view's body subset) is seeded from a tuple of words by splitmix64, so any member can
//! be re-run alone and no random state is ever saved. A leaf module: the drivers import
//! it, it imports none of them.

/// splitmix64 finaliser: a bijective 64-bit mixer.
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash a sequence of words into one seed (each word mixed into the running state).
pub fn derive_seed(words: &[u64]) -> u64 {
    words
        .iter()
        .fold(0x6A09_E667_F3BC_C908, |h, &w| splitmix64(h ^ splitmix64(w)))
}
