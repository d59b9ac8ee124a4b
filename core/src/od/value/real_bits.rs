//! IEEE 754 double precision on the bits of numbers, for the limits and defaults of real
//! entries: exactly what the conversions `as f64`, `as f32`, `as i64` and `as u64` and
//! `f64::partial_cmp` give, in integer arithmetic. A processor without double precision (a Cortex-M4F has single precision only)
//! would otherwise link the compiler's software floating point for them, a kilobyte of code
//! that a dictionary without real limits never runs.

/// The 52 bits of a double's fraction.
const FRACTION: u64 = (1 << 52) - 1;
/// A double's exponent bias.
const BIAS: u64 = 1023;

/// True for a NaN (exponent all ones, fraction not zero).
fn is_nan(x: u64) -> bool {
    (x >> 52) & 0x7FF == 0x7FF && x & FRACTION != 0
}

/// `f32::from_bits(b) as f64`, as bits (exact: every single is a double; a NaN stays a NaN).
pub(super) fn f32_to_f64(b: u32) -> u64 {
    let sign = u64::from(b >> 31) << 63;
    let exp = u64::from((b >> 23) & 0xFF);
    let man = u64::from(b & 0x7F_FFFF);
    match exp {
        // Infinity or NaN.
        0xFF => sign | 0x7FF << 52 | man << 29,
        0 if man == 0 => sign,
        // Subnormal, `man × 2^-149`: normal as a double, its top bit the hidden one.
        0 => {
            let top = 63 - u64::from(man.leading_zeros());
            sign | (top + BIAS - 149) << 52 | (man << (52 - top)) & FRACTION
        }
        _ => sign | (exp + BIAS - 127) << 52 | man << 29,
    }
}

/// `f64::from_bits(b) as f32`, as bits: rounded to the nearest single, ties to even (beyond
/// the largest, infinity; below the smallest subnormal's half, zero). A NaN stays a NaN.
pub(super) fn f64_to_f32(b: u64) -> u32 {
    let sign = ((b >> 63) as u32) << 31;
    let exp = (b >> 52) & 0x7FF;
    let man = b & FRACTION;
    if exp == 0x7FF {
        let nan = if man != 0 {
            0x40_0000 | (man >> 29) as u32
        } else {
            0
        };
        return sign | 0x7F80_0000 | nan;
    }
    // Zero, or a subnormal double: far below a single's smallest subnormal.
    if exp == 0 {
        return sign;
    }
    // The single's biased exponent; at 255 and above, infinity.
    let e = exp as i64 - BIAS as i64 + 127;
    if e >= 255 {
        return sign | 0x7F80_0000;
    }
    // 53 bits of significand down to 24 (a normal single) or fewer (a subnormal one).
    let m = man | 1 << 52;
    let shift = 29 + (1 - e).max(0) as u64;
    if shift >= 64 {
        return sign;
    }
    let kept = m >> shift;
    let rest = m & ((1 << shift) - 1);
    let half = 1 << (shift - 1);
    let kept = kept + u64::from(rest > half || (rest == half && kept & 1 == 1));
    // The hidden bit carries into the exponent field (and a round-up past the largest
    // significand into the next exponent, up to infinity).
    sign | ((((e - 1).max(0) as u64) << 23) + kept) as u32
}

/// `x as f64`, as bits: rounded to the nearest double, ties to even.
pub(super) fn u64_to_f64(x: u64) -> u64 {
    if x == 0 {
        return 0;
    }
    let mut top = 63 - u64::from(x.leading_zeros());
    let mut man = if top <= 52 {
        x << (52 - top)
    } else {
        let shift = top - 52;
        let kept = x >> shift;
        let rest = x & ((1 << shift) - 1);
        let half = 1 << (shift - 1);
        kept + u64::from(rest > half || (rest == half && kept & 1 == 1))
    };
    // Rounded up to the next power of two.
    if man >> 53 != 0 {
        man >>= 1;
        top += 1;
    }
    (top + BIAS) << 52 | man & FRACTION
}

/// `x as f64`, as bits.
pub(super) fn i64_to_f64(x: i64) -> u64 {
    u64::from(x < 0) << 63 | u64_to_f64(x.unsigned_abs())
}

/// `f64::from_bits(a).partial_cmp(&f64::from_bits(b))`.
pub(super) fn cmp(a: u64, b: u64) -> Option<core::cmp::Ordering> {
    if is_nan(a) || is_nan(b) {
        return None;
    }
    // +0 and -0 are equal; otherwise sign and magnitude order as the integers below.
    if (a | b) << 1 == 0 {
        return Some(core::cmp::Ordering::Equal);
    }
    let key = |x: u64| if x >> 63 == 1 { !x } else { x | 1 << 63 };
    Some(key(a).cmp(&key(b)))
}

/// The magnitude of a double of at least 1 rounded toward zero, if it is below `2^limit`
/// (`limit` ≤ 64); `None` beyond (infinity included).
fn whole(b: u64, limit: u64) -> Option<u64> {
    let e = ((b >> 52) & 0x7FF) - BIAS;
    if e >= limit {
        return None;
    }
    let man = b & FRACTION | 1 << 52;
    Some(if e >= 52 {
        man << (e - 52)
    } else {
        man >> (52 - e)
    })
}

/// `f64::from_bits(b) as u64`: toward zero, saturating, NaN 0.
pub(super) fn f64_to_u64(b: u64) -> u64 {
    if is_nan(b) || b >> 63 == 1 || (b >> 52) & 0x7FF < BIAS {
        return 0;
    }
    whole(b, 64).unwrap_or(u64::MAX)
}

/// `f64::from_bits(b) as i64`: toward zero, saturating, NaN 0.
pub(super) fn f64_to_i64(b: u64) -> i64 {
    if is_nan(b) || (b >> 52) & 0x7FF < BIAS {
        return 0;
    }
    let negative = b >> 63 == 1;
    match whole(b, 63) {
        Some(m) if negative => -(m as i64),
        Some(m) => m as i64,
        None if negative => i64::MIN,
        None => i64::MAX,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit patterns of every kind: random, and the edges (zeros, subnormals, powers of two,
    /// the integers' limits, infinities, NaNs) with their neighbours.
    fn doubles() -> Vec<u64> {
        let mut rng = fastrand::Rng::with_seed(3);
        let mut v: Vec<u64> = (0..50_000).map(|_| rng.u64(..)).collect();
        // Exponents near the integers' range, where the conversions round and saturate.
        v.extend((0..50_000).map(|_| {
            let exp = rng.u64(BIAS - 2..=BIAS + 66);
            u64::from(rng.bool()) << 63 | exp << 52 | rng.u64(..) & FRACTION
        }));
        for x in [
            0.0f64,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2f64.powi(52),
            2f64.powi(53),
            2f64.powi(63),
            -(2f64.powi(63)),
            2f64.powi(64),
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            let b = x.to_bits();
            v.extend([b, b.wrapping_add(1), b.wrapping_sub(1)]);
        }
        v.extend([1, 0x7FF0_0000_0000_0001, 0xFFF8_0000_0000_0000]);
        v
    }

    #[test]
    fn conversions_from_doubles_are_the_languages() {
        for b in doubles() {
            let x = f64::from_bits(b);
            assert_eq!(f64_to_u64(b), x as u64, "{x:e} ({b:#x}) as u64");
            assert_eq!(f64_to_i64(b), x as i64, "{x:e} ({b:#x}) as i64");
        }
    }

    #[test]
    fn singles_from_doubles_are_the_languages() {
        let mut v = doubles();
        let mut rng = fastrand::Rng::with_seed(13);
        // Exponents around a single's range: subnormals, rounding, overflow.
        v.extend((0..200_000).map(|_| {
            let exp = rng.u64(BIAS - 155..=BIAS + 130);
            let man = match rng.u8(0..4) {
                // Exactly halfway, and one off it, for some shift.
                0 => (rng.u64(..) & FRACTION) >> 29 << 29 | 1 << 28,
                1 => ((rng.u64(..) & FRACTION) >> 29 << 29 | 1 << 28) + 1,
                2 => FRACTION,
                _ => rng.u64(..) & FRACTION,
            };
            u64::from(rng.bool()) << 63 | exp << 52 | man
        }));
        v.extend(
            [
                f32::MAX as f64,
                f64::from(f32::MIN_POSITIVE),
                1e-45,
                7e-46,
                1.5e-45,
            ]
            .map(f64::to_bits),
        );
        for b in v {
            let want = f64::from_bits(b) as f32;
            let got = f32::from_bits(f64_to_f32(b));
            if want.is_nan() {
                assert!(got.is_nan(), "{b:#x}");
            } else {
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "{:e} ({b:#x})",
                    f64::from_bits(b)
                );
            }
        }
    }

    #[test]
    fn comparisons_are_the_languages() {
        let v = doubles();
        let mut rng = fastrand::Rng::with_seed(5);
        for _ in 0..200_000 {
            let (a, b) = (v[rng.usize(..v.len())], v[rng.usize(..v.len())]);
            let want = f64::from_bits(a).partial_cmp(&f64::from_bits(b));
            assert_eq!(cmp(a, b), want, "{a:#x} vs {b:#x}");
            assert_eq!(cmp(a, a), f64::from_bits(a).partial_cmp(&f64::from_bits(a)));
        }
    }

    #[test]
    fn conversions_to_doubles_are_the_languages() {
        let mut rng = fastrand::Rng::with_seed(9);
        let mut ints: Vec<u64> = (0..100_000)
            .map(|_| rng.u64(..) >> rng.u32(0..64))
            .collect();
        for k in 0..64 {
            let p = 1u64 << k;
            ints.extend([p, p - 1, p + 1, p | p >> 1, (p | p >> 1) + 1]);
        }
        ints.extend([0, u64::MAX, u64::MAX - 1, i64::MAX as u64, i64::MIN as u64]);
        // Halfway cases of every rounding shift: kept bits then exactly half.
        for shift in 1..=11u32 {
            for kept in [(1u64 << 52) | 1, 1 << 52, (1 << 53) - 1] {
                let top = kept << shift;
                ints.extend([top | 1 << (shift - 1), (top | 1 << (shift - 1)) + 1]);
            }
        }
        for x in ints {
            assert_eq!(u64_to_f64(x), (x as f64).to_bits(), "{x} as f64");
            let s = x as i64;
            assert_eq!(i64_to_f64(s), (s as f64).to_bits(), "{s} as f64");
        }
        for b in (0..200_000u32).map(|_| rng.u32(..)).chain([
            0,
            1,
            0x7F_FFFF,
            0x80_0000,
            0x8000_0001,
            0x7F80_0000,
            0xFF80_0000,
        ]) {
            let want = f32::from_bits(b) as f64;
            let got = f64::from_bits(f32_to_f64(b));
            if want.is_nan() {
                assert!(got.is_nan(), "{b:#x}");
            } else {
                assert_eq!(got.to_bits(), want.to_bits(), "{b:#x}");
            }
        }
    }
}
