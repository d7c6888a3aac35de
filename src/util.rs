//! Small helpers shared by several stages.

/// 64-bit FNV-1a hash: stable across platforms and versions, used for config and scene content hashes.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Reads a whole regular file (symlinks followed) of at most `max_bytes`. A device (`/dev/zero`), a
/// FIFO (which would block with no writer) or a folder is refused before it is opened, and the read
/// itself stops at the bound, so no input can make the program read without end.
pub fn read_regular_file(path: &std::path::Path, max_bytes: u64) -> crate::Result<Vec<u8>> {
    use crate::Error;
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a folder"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(Error::scene(path, format!("is {what}; expected a file")));
    }
    if meta.len() > max_bytes {
        return Err(Error::scene(
            path,
            format!(
                "file of {} bytes exceeds the {max_bytes}-byte limit",
                meta.len()
            ),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(Error::scene(
            path,
            format!("file exceeds the {max_bytes}-byte limit"),
        ));
    }
    Ok(bytes)
}

/// A number for a message: plain when it reads well, scientific when it is huge or tiny, so that a
/// value like 1e-300 prints as `1e-300` and not as 300 digits.
pub fn short_number(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-4..1e7).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Wraps an angle to (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let mut a = a % std::f64::consts::TAU;
    if a > std::f64::consts::PI {
        a -= std::f64::consts::TAU;
    } else if a <= -std::f64::consts::PI {
        a += std::f64::consts::TAU;
    }
    a
}

/// SplitMix64's output function (Steele, Lea and Flood, "Fast splittable pseudorandom number
/// generators", OOPSLA 2014): a bijective 64-bit mix whose outputs pass BigCrush for consecutive
/// inputs.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A counter-based random generator: each draw is a pure function of a key (the run's seed and a
/// stream) and a counter (frame, pixel, channel), so a draw never depends on how many draws came
/// before it, on the order work is done in, or on the thread count.
#[derive(Clone, Copy, Debug)]
pub struct CounterRng {
    key: u64,
}

impl CounterRng {
    /// The generator of stream `stream` of seed `seed`.
    pub fn new(seed: u64, stream: u64) -> CounterRng {
        CounterRng {
            key: splitmix64(splitmix64(seed) ^ stream.rotate_left(32)),
        }
    }

    /// The key of counter `(a, b)`: every draw of that counter derives from it with one more mix
    /// ([`CounterRng::uniform_of`]), so that many draws for one counter cost little.
    #[inline]
    pub fn key(&self, a: u64, b: u64) -> u64 {
        splitmix64(splitmix64(self.key ^ a) ^ b)
    }

    /// 64 random bits for counter `(a, b, c)`.
    #[inline]
    pub fn bits(&self, a: u64, b: u64, c: u64) -> u64 {
        Self::bits_of(self.key(a, b), c)
    }

    /// 64 random bits for draw `c` of a counter's `key` ([`CounterRng::key`]).
    #[inline]
    pub fn bits_of(key: u64, c: u64) -> u64 {
        splitmix64(key ^ c.wrapping_mul(0xd1b5_4a32_d192_ed03))
    }

    /// Uniform in the open interval (0, 1) for draw `c` of a counter's `key`: 53 bits, never 0 or
    /// 1.
    #[inline]
    pub fn uniform_of(key: u64, c: u64) -> f64 {
        ((Self::bits_of(key, c) >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in the open interval (0, 1) for counter `(a, b, c)`.
    #[inline]
    pub fn uniform(&self, a: u64, b: u64, c: u64) -> f64 {
        Self::uniform_of(self.key(a, b), c)
    }

    /// A standard normal draw for counter `(a, b, c)` by the Box–Muller transform of two uniforms
    /// (draws `2c` and `2c + 1`).
    #[inline]
    pub fn normal(&self, a: u64, b: u64, c: u64) -> f64 {
        let key = self.key(a, b);
        let u1 = Self::uniform_of(key, 2 * c);
        let u2 = Self::uniform_of(key, 2 * c + 1);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding (how Foxglove's JSON encoding carries `bytes` fields).
pub fn base64_encode(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(B64[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Inverse of [`base64_encode`]; `None` on a character outside the alphabet.
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0;
    for c in text.bytes().filter(|&c| c != b'=') {
        let v = B64.iter().position(|&a| a == c)? as u32;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

/// Runs `f` on a rayon pool of its own with `threads` threads: tests that check results do not
/// depend on the thread count.
#[cfg(test)]
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn base64_known_answers_and_round_trip() {
        assert_eq!(base64_encode(b""), "");
        assert_eq!(base64_encode(b"f"), "Zg==");
        assert_eq!(base64_encode(b"fo"), "Zm8=");
        assert_eq!(base64_encode(b"foobar"), "Zm9vYmFy");
        let bytes: Vec<u8> = (0..=255).collect();
        assert_eq!(base64_decode(&base64_encode(&bytes)).unwrap(), bytes);
        assert_eq!(base64_decode("Zm8="), Some(b"fo".to_vec()));
        assert_eq!(base64_decode("Z!"), None);
    }

    #[test]
    fn fnv_known_vectors() {
        // Reference values of FNV-1a 64.
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }

    /// SplitMix64's published first outputs for seed 0 (the state advances by the golden gamma).
    #[test]
    fn splitmix_known_answers() {
        assert_eq!(splitmix64(0), 0xe220_a839_7b1d_cdaf);
        assert_eq!(splitmix64(0x9e37_79b9_7f4a_7c15), 0x6e78_9e6a_a1b9_65f4);
    }

    /// The counter generator's uniforms and normals have the moments of their distributions, and a
    /// draw depends only on its key and counter.
    #[test]
    fn counter_rng_moments_and_purity() {
        let rng = CounterRng::new(7, 1);
        let n = 200_000;
        let (mut s1, mut s2, mut u_sum) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let u = rng.uniform(3, i, 0);
            assert!(u > 0.0 && u < 1.0);
            u_sum += u;
            let z = rng.normal(3, i, 1);
            s1 += z;
            s2 += z * z;
        }
        let nf = n as f64;
        assert!((u_sum / nf - 0.5).abs() < 0.005, "{}", u_sum / nf);
        let mean = s1 / nf;
        let var = s2 / nf - mean * mean;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
        assert_eq!(rng.bits(1, 2, 3), CounterRng::new(7, 1).bits(1, 2, 3));
        assert_ne!(rng.bits(1, 2, 3), CounterRng::new(7, 2).bits(1, 2, 3));
        assert_ne!(rng.bits(1, 2, 3), CounterRng::new(8, 1).bits(1, 2, 3));
    }

    #[test]
    fn wrap_angle_range() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-12);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
    }
}
