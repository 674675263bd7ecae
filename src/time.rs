//! Time stamps relative to a reference epoch.
//!
//! Unix times near 1.7e9 s keep only about 0.2 us of precision in an f64, and differences of
//! such numbers lose more. Every time inside dvlcal is therefore an f64 number of seconds
//! relative to an integer epoch (whole seconds), chosen per dataset. Text time stamps are split
//! into their integer and fractional parts before the epoch is subtracted, so no digit is lost.

/// An integer number of seconds that all relative times of a dataset are counted from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Epoch {
    /// Whole seconds on the clock of the source (e.g. Unix seconds).
    pub sec: i64,
}

/// A time stamp parsed exactly from text: whole seconds and a fraction in [0, 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawTime {
    /// Whole seconds (the floor of the time stamp).
    pub sec: i64,
    /// Fraction of a second, in [0, 1).
    pub frac: f64,
}

/// `i64::MIN` as f64 (exactly -2^63), the smallest whole second a time stamp may have.
const I64_MIN_F64: f64 = i64::MIN as f64;
/// 2^63, just past the largest whole second a time stamp may have.
const I64_END_F64: f64 = 9_223_372_036_854_775_808.0;

impl RawTime {
    /// Parses a decimal time stamp such as `1718000000.123456789` or `12.5` or `-3.25`, keeping the
    /// whole seconds exact. Returns `None` for anything else (including NaN, infinities and whole
    /// seconds outside the i64 range).
    pub fn parse(s: &str) -> Option<RawTime> {
        let s = s.trim();
        if s.is_empty() {
            return None;
        }
        // Scientific notation (e.g. 1.5e9) is accepted through f64 when it carries no fraction
        // that would be lost.
        if s.contains(['e', 'E']) {
            let v: f64 = s.parse().ok()?;
            // Whole seconds beyond i64 (and NaN, infinities) are not a time stamp: a saturating
            // cast would silently move them to the end of the range.
            if !(I64_MIN_F64..I64_END_F64).contains(&v) {
                return None;
            }
            let sec = v.floor();
            return RawTime::normalized(sec as i64, v - sec);
        }
        let (neg, body) = match s.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, s.strip_prefix('+').unwrap_or(s)),
        };
        let (int_part, frac_part) = match body.split_once('.') {
            Some((i, f)) => (i, f),
            None => (body, ""),
        };
        if int_part.is_empty() && frac_part.is_empty() {
            return None;
        }
        if !int_part.bytes().all(|b| b.is_ascii_digit())
            || !frac_part.bytes().all(|b| b.is_ascii_digit())
        {
            return None;
        }
        let whole: i64 = if int_part.is_empty() {
            0
        } else {
            int_part.parse().ok()?
        };
        let frac: f64 = if frac_part.is_empty() {
            0.0
        } else {
            format!("0.{frac_part}").parse().ok()?
        };
        if neg {
            if frac > 0.0 {
                RawTime::normalized(-whole - 1, 1.0 - frac)
            } else {
                Some(RawTime {
                    sec: -whole,
                    frac: 0.0,
                })
            }
        } else {
            RawTime::normalized(whole, frac)
        }
    }

    /// `sec + frac` with `frac` in [0, 1]: a fraction rounded up to 1 (`0.99999999999999999`,
    /// or `-1e-20` in scientific notation) carries into the seconds. `None` when that leaves the
    /// i64 range.
    fn normalized(sec: i64, frac: f64) -> Option<RawTime> {
        if frac >= 1.0 {
            Some(RawTime {
                sec: sec.checked_add(1)?,
                frac: 0.0,
            })
        } else {
            Some(RawTime { sec, frac })
        }
    }

    /// A time from integer nanoseconds (ROS stamps, image file names).
    pub fn from_nanos(ns: i64) -> RawTime {
        // One division of exact integers: the fraction is the double nearest the decimal one,
        // as a time written in decimal and parsed is.
        RawTime {
            sec: ns.div_euclid(1_000_000_000),
            frac: ns.rem_euclid(1_000_000_000) as f64 / 1e9,
        }
    }

    /// Builds a raw time from integer microseconds (the A50's `time_of_validity`).
    pub fn from_micros(us: i64) -> RawTime {
        RawTime {
            sec: us.div_euclid(1_000_000),
            frac: us.rem_euclid(1_000_000) as f64 * 1e-6,
        }
    }
}

impl Epoch {
    /// The epoch at the whole second of `t`.
    pub fn at(t: RawTime) -> Epoch {
        Epoch { sec: t.sec }
    }

    /// Seconds from this epoch to `t`.
    pub fn rel(&self, t: RawTime) -> f64 {
        // In i128: a time stamp far from the epoch (both anywhere in i64) cannot overflow.
        (i128::from(t.sec) - i128::from(self.sec)) as f64 + t.frac
    }

    /// Formats the relative time `t` as an absolute decimal time stamp with `decimals` digits after
    /// the point, without passing through a large f64.
    pub fn format_abs(&self, t: f64, decimals: usize) -> String {
        let whole = t.floor();
        // Saturating: a relative time beyond the i64 range of seconds prints as its end.
        let mut sec = self.sec.saturating_add(whole as i64);
        let frac = t - whole;
        let scale = 10f64.powi(decimals as i32);
        let mut frac_digits = (frac * scale).round() as i64;
        if frac_digits as f64 >= scale {
            frac_digits -= scale as i64;
            sec = sec.saturating_add(1);
        }
        if decimals == 0 {
            return format!("{sec}");
        }
        if sec < 0 && frac_digits > 0 {
            // Negative absolute times: write as -(|x|) exactly.
            let total_frac = scale as i64 - frac_digits;
            return format!("-{}.{:0width$}", -(sec + 1), total_frac, width = decimals);
        }
        format!("{sec}.{frac_digits:0width$}", width = decimals)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_unix_time_without_losing_digits() {
        let t = RawTime::parse("1718000000.123456789").unwrap();
        assert_eq!(t.sec, 1_718_000_000);
        assert!((t.frac - 0.123456789).abs() < 1e-15);
        let e = Epoch { sec: 1_718_000_000 };
        assert_eq!(e.format_abs(e.rel(t), 9), "1718000000.123456789");
    }

    #[test]
    fn negative_and_plain_forms() {
        let t = RawTime::parse("-3.25").unwrap();
        assert_eq!((t.sec, t.frac), (-4, 0.75));
        assert_eq!(RawTime::parse("12").unwrap().sec, 12);
        assert_eq!(RawTime::parse(".5").unwrap().frac, 0.5);
        for bad in ["", "abc", "1.2.3", "nan", "inf", "1,5", "-", "."] {
            assert!(RawTime::parse(bad).is_none(), "{bad} accepted");
        }
        let e = Epoch { sec: 0 };
        assert_eq!(e.format_abs(-3.25, 3), "-3.250");
    }

    #[test]
    fn micros_round_trip() {
        let t = RawTime::from_micros(1_550_000_000_123_456);
        let e = Epoch { sec: 1_550_000_000 };
        assert!((e.rel(t) - 0.123456).abs() < 1e-12);
        assert_eq!(e.format_abs(e.rel(t), 6), "1550000000.123456");
    }

    #[test]
    fn extreme_time_stamps_neither_saturate_nor_overflow() {
        // Whole seconds beyond i64 are refused, not clamped to its ends.
        for bad in [
            "-3.2e95",
            "1e19",
            "9223372036854775808",
            "-9223372036854775809",
        ] {
            assert!(RawTime::parse(bad).is_none(), "{bad} accepted");
        }
        // The ends of the range are times, and their distance from any epoch is a number.
        let lo = RawTime::parse("-9223372036854775807.5").unwrap();
        let hi = RawTime::parse("9223372036854775807.5").unwrap();
        let e = Epoch { sec: 1_700_000_000 };
        assert!(e.rel(lo) < -9.2e18 && e.rel(hi) > 9.2e18);
        assert!(Epoch { sec: i64::MAX }.rel(lo) < -1.8e19);
        assert!(
            Epoch { sec: i64::MIN }
                .format_abs(-1e30, 3)
                .starts_with('-')
        );
    }

    #[test]
    fn a_fraction_rounded_to_one_carries() {
        // Twenty nines round to 1.0 as an f64; a tiny negative number in scientific notation
        // leaves 1 - 1e-20 = 1.0 as its fraction. Both are the next whole second.
        let t = RawTime::parse("4.99999999999999999999").unwrap();
        assert_eq!((t.sec, t.frac), (5, 0.0));
        let t = RawTime::parse("-1e-20").unwrap();
        assert_eq!((t.sec, t.frac), (0, 0.0));
        assert!(RawTime::parse("9223372036854775807.99999999999999999999").is_none());
    }
}
