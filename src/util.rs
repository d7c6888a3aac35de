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

/// The standard normal quantile Φ⁻¹(p) for p in (0, 1): Wichura's algorithm AS 241 (PPND16,
/// "The percentage points of the normal distribution", Applied Statistics 37(3), 1988), accurate
/// to about 1e-16. A normal draw from one uniform, with no transcendental function for 85 % of
/// draws (|p − ½| ≤ 0.425).
// The coefficients are Wichura's published digits, more than an f64 holds.
#[allow(clippy::excessive_precision)]
pub fn normal_quantile(p: f64) -> f64 {
    fn poly(c: &[f64], x: f64) -> f64 {
        c.iter().rev().fold(0.0, |acc, &k| acc * x + k)
    }
    // Wichura's coefficients, lowest power first.
    const A: [f64; 8] = [
        3.387_132_872_796_366_608,
        1.331_416_678_917_843_774_5e2,
        1.971_590_950_306_551_442_7e3,
        1.373_169_376_550_946_112_5e4,
        4.592_195_393_154_987_145_7e4,
        6.726_577_092_700_870_085_3e4,
        3.343_057_558_358_812_810_5e4,
        2.509_080_928_730_122_672_7e3,
    ];
    const B: [f64; 8] = [
        1.0,
        4.231_333_070_160_091_125_2e1,
        6.871_870_074_920_579_083e2,
        5.394_196_021_424_751_107_7e3,
        2.121_379_430_158_659_586_7e4,
        3.930_789_580_009_271_061e4,
        2.872_908_573_572_194_267_4e4,
        5.226_495_278_852_854_561e3,
    ];
    const C: [f64; 8] = [
        1.423_437_110_749_683_577_34,
        4.630_337_846_156_545_295_9,
        5.769_497_221_460_691_405_5,
        3.647_848_324_763_204_605_04,
        1.270_458_252_452_368_382_58,
        2.417_807_251_774_506_117_7e-1,
        2.272_384_498_926_918_458_33e-2,
        7.745_450_142_783_414_076_4e-4,
    ];
    const D: [f64; 8] = [
        1.0,
        2.053_191_626_637_758_821_87,
        1.676_384_830_183_803_849_4,
        6.897_673_349_851_000_045_5e-1,
        1.481_039_764_274_800_745_9e-1,
        1.519_866_656_361_645_719_66e-2,
        5.475_938_084_995_344_946e-4,
        1.050_750_071_644_416_843_24e-9,
    ];
    const E: [f64; 8] = [
        6.657_904_643_501_103_777_2,
        5.463_784_911_164_114_369_9,
        1.784_826_539_917_291_335_8,
        2.965_605_718_285_048_912_3e-1,
        2.653_218_952_657_612_309_3e-2,
        1.242_660_947_388_078_438_6e-3,
        2.711_555_568_743_487_578_15e-5,
        2.010_334_399_292_288_132_65e-7,
    ];
    const F: [f64; 8] = [
        1.0,
        5.998_322_065_558_879_376_9e-1,
        1.369_298_809_227_358_053_1e-1,
        1.487_536_129_085_061_485_25e-2,
        7.868_691_311_456_132_591e-4,
        1.846_318_317_510_054_681_8e-5,
        1.421_511_758_316_445_888_7e-7,
        2.044_263_103_389_939_785_64e-15,
    ];
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        let r = 0.180_625 - q * q;
        return q * poly(&A, r) / poly(&B, r);
    }
    let r = if q < 0.0 { p } else { 1.0 - p };
    let r = (-r.ln()).sqrt();
    let x = if r <= 5.0 {
        let r = r - 1.6;
        poly(&C, r) / poly(&D, r)
    } else {
        let r = r - 5.0;
        poly(&E, r) / poly(&F, r)
    };
    if q < 0.0 {
        -x
    } else {
        x
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

/// Runs `f` on a worker of the process's run pool, built on first use and sized as rayon's global
/// pool would be (`RAYON_NUM_THREADS`, else one thread per core), with the main thread's usual
/// 8 MiB of stack. A run's parallel loops then start on the thread that asks for them: with one
/// thread nothing is handed to another thread, and with two the calling thread takes part instead
/// of waiting for the pool at every loop (which cost a Python process's runs a fifth of their wall
/// time with two threads). If the pool cannot be built, `f` runs here.
pub fn on_run_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    static POOL: std::sync::OnceLock<Option<rayon::ThreadPool>> = std::sync::OnceLock::new();
    let pool = POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .stack_size(8 << 20)
            .build()
            .ok()
    });
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

/// The message a panic carried (`panic!` with a literal or a formatted string), for rows and
/// errors that report a caught panic.
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
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

    /// Known quantiles of the standard normal distribution.
    #[test]
    fn normal_quantile_known_answers() {
        for (p, x) in [
            (0.5, 0.0),
            (0.975, 1.959_963_984_540_054),
            (0.025, -1.959_963_984_540_054),
            (0.841_344_746_068_542_9, 1.0),
            (1e-10, -6.361_340_902_404_056),
            (0.999, 3.090_232_306_167_813_5),
        ] {
            assert!(
                (normal_quantile(p) - x).abs() < 1e-9,
                "{p}: {}",
                normal_quantile(p)
            );
        }
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
