//! How sure a timing is. A benchmark times the same work several times; a single timing on a
//! busy device (another process, a clock change, a CPU implementation of Vulkan) can be off by
//! more than the effect it is meant to show. So every row keeps all its timings, reports their
//! median (robust to one disturbed timing) and their spread, and a difference between two rows
//! is reported as a cost only where the timings agree on its sign.
//!
//! * The **spread** of a row is its interquartile range `q₇₅ − q₂₅` (quantiles by linear
//!   interpolation between the sorted timings): the width of the middle half of them.
//! * Two rows timed **in alternating order** (repeat `r` times row A then row B, repeat `r + 1`
//!   B then A, ...) give a **paired difference** `d_r = t_B,r − t_A,r` per repeat: a slow spell
//!   of the device falls on both members of a pair, so it cancels in `d_r`.
//! * The difference **stands out of the noise** when the middle half of the paired differences
//!   lies on one side of zero: `q₂₅(d) > 0` (B costs `median(d)` more) or `q₇₅(d) < 0` (B
//!   saves `−median(d)`). Otherwise it is **inside the noise**, reported with the range
//!   `q₂₅(d) … q₇₅(d)` rather than as a number, never as a negative cost and never as zero.

/// Timings of each benchmark row by default (`cloth bench --repeats` chooses another count):
/// enough for the middle half of the timings to leave out one disturbed timing at each end.
pub const DEFAULT_REPEATS: u32 = 5;

/// Repeated timings of one quantity (e.g. ms per frame), in the order they were taken.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples(Vec<f64>);

impl Samples {
    /// The timings; at least one, each finite.
    ///
    /// # Panics
    /// On an empty list or a non-finite timing (a measurement's own bug, not input).
    pub fn new(values: Vec<f64>) -> Self {
        assert!(!values.is_empty() && values.iter().all(|v| v.is_finite()), "timings: {values:?}");
        Self(values)
    }

    /// The timings in the order they were taken.
    pub fn values(&self) -> &[f64] {
        &self.0
    }

    /// How many timings.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Never: a `Samples` holds at least one timing.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The `q`-quantile (`0 ≤ q ≤ 1`), linearly interpolated between the sorted timings.
    pub fn quantile(&self, q: f64) -> f64 {
        let mut sorted = self.0.clone();
        sorted.sort_by(f64::total_cmp);
        let at = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
        let (below, above) = (at.floor() as usize, at.ceil() as usize);
        sorted[below] + (sorted[above] - sorted[below]) * (at - below as f64)
    }

    /// The median: the 0.5-quantile.
    pub fn median(&self) -> f64 {
        self.quantile(0.5)
    }

    /// The interquartile range `q₇₅ − q₂₅`: how far apart the middle half of the timings are.
    pub fn spread(&self) -> f64 {
        self.quantile(0.75) - self.quantile(0.25)
    }

    /// `t_self,r − t_earlier,r` for each repeat `r`: the paired differences of two rows timed
    /// in alternating order, as many as the shorter of the two has.
    pub fn paired_minus(&self, earlier: &Samples) -> Samples {
        Samples::new(self.0.iter().zip(&earlier.0).map(|(a, b)| a - b).collect())
    }
}

/// What the paired differences of two rows say (see the module's documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Difference {
    /// The middle half of the differences is above zero: the later row costs `median` more.
    Costs {
        /// The median difference, > 0.
        median: f64,
        /// `q₂₅` of the differences, > 0.
        low: f64,
        /// `q₇₅` of the differences.
        high: f64,
    },
    /// The middle half of the differences contains zero: the difference is smaller than the
    /// noise, which spans `low ≤ 0 ≤ high`.
    InsideNoise {
        /// `q₂₅` of the differences, ≤ 0.
        low: f64,
        /// `q₇₅` of the differences, ≥ 0.
        high: f64,
    },
    /// The middle half of the differences is below zero: the later row is faster by `−median`.
    Saves {
        /// The median difference, < 0.
        median: f64,
        /// `q₂₅` of the differences.
        low: f64,
        /// `q₇₅` of the differences, < 0.
        high: f64,
    },
}

impl Difference {
    /// Classifies the paired differences `d` of two rows.
    pub fn of(d: &Samples) -> Self {
        let (low, median, high) = (d.quantile(0.25), d.median(), d.quantile(0.75));
        if low > 0.0 {
            Self::Costs { median, low, high }
        } else if high < 0.0 {
            Self::Saves { median, low, high }
        } else {
            Self::InsideNoise { low, high }
        }
    }

    /// The cost that stands out of the noise (`Costs`' median), else `None`.
    pub fn cost(&self) -> Option<f64> {
        match self {
            Self::Costs { median, .. } => Some(*median),
            _ => None,
        }
    }

    /// The median difference where it stands out of the noise (`Costs`: > 0, `Saves`: < 0),
    /// else `None`.
    pub fn outside_noise(&self) -> Option<f64> {
        match self {
            Self::Costs { median, .. } | Self::Saves { median, .. } => Some(*median),
            Self::InsideNoise { .. } => None,
        }
    }

    /// One word for a CSV column: `costs`, `inside_noise` or `saves`.
    pub fn verdict(&self) -> &'static str {
        match self {
            Self::Costs { .. } => "costs",
            Self::InsideNoise { .. } => "inside_noise",
            Self::Saves { .. } => "saves",
        }
    }

    /// `(q₂₅, q₇₅)` of the differences: the range of their middle half.
    pub fn range(&self) -> (f64, f64) {
        match *self {
            Self::Costs { low, high, .. } | Self::InsideNoise { low, high } | Self::Saves { low, high, .. } => {
                (low, high)
            }
        }
    }

    /// In words, with `unit` after each number: `+1.234 ms`, `inside the noise (-0.2 to +0.3
    /// ms)` or `saves 0.500 ms`.
    pub fn describe(&self, unit: &str) -> String {
        match *self {
            Self::Costs { median, .. } => format!("+{median:.3} {unit}"),
            Self::InsideNoise { low, high } => format!("inside the noise ({low:+.3} to {high:+.3} {unit})"),
            Self::Saves { median, .. } => format!("saves {:.3} {unit}", -median),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_spread_interpolate_the_sorted_timings() {
        let s = Samples::new(vec![5.0, 1.0, 4.0, 2.0, 3.0]);
        assert_eq!((s.median(), s.quantile(0.25), s.quantile(0.75), s.spread()), (3.0, 2.0, 4.0, 2.0));
        let even = Samples::new(vec![4.0, 1.0, 3.0, 2.0]);
        assert_eq!((even.median(), even.quantile(0.25)), (2.5, 1.75));
        // One disturbed timing moves neither the median nor, here, the spread much.
        let disturbed = Samples::new(vec![1.0, 1.1, 0.9, 1.0, 50.0]);
        assert_eq!(disturbed.median(), 1.0);
        assert!((disturbed.spread() - 0.1).abs() < 1e-12);
        assert_eq!(Samples::new(vec![7.0]).spread(), 0.0);
    }

    #[test]
    fn a_difference_counts_only_where_the_middle_half_agrees_on_its_sign() {
        let a = Samples::new(vec![10.0, 12.0, 10.5, 11.0, 10.2]);
        // Every pair 1 ms slower, whatever the device did: a cost of 1 ms.
        let slower = Samples::new(a.values().iter().map(|t| t + 1.0).collect());
        let d = Difference::of(&slower.paired_minus(&a));
        assert_eq!(d.verdict(), "costs");
        assert!((d.cost().unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(d.describe("ms"), "+1.000 ms");
        // The lavapipe flag-scene case: a row faster in some repeats and slower in others.
        let noisy = Samples::new(vec![8.6, 13.5, 10.6, 9.4, 11.9]);
        let d = Difference::of(&noisy.paired_minus(&a));
        assert_eq!((d.verdict(), d.cost()), ("inside_noise", None));
        let (low, high) = d.range();
        assert!(low <= 0.0 && high >= 0.0);
        assert!(d.describe("ms").starts_with("inside the noise ("), "{}", d.describe("ms"));
        // Consistently faster: said as a saving, never as a negative cost.
        let faster = Samples::new(a.values().iter().map(|t| t - 0.5).collect());
        let d = Difference::of(&faster.paired_minus(&a));
        assert_eq!((d.verdict(), d.describe("ms")), ("saves", "saves 0.500 ms".to_string()));
    }

    #[test]
    fn no_description_is_a_negative_cost() {
        // Every sign pattern of five paired differences.
        for pattern in 0u32..32 {
            let d: Vec<f64> =
                (0..5).map(|k| if pattern >> k & 1 == 1 { 0.1 * (k + 1) as f64 } else { -0.2 * k as f64 }).collect();
            let text = Difference::of(&Samples::new(d.clone())).describe("ms");
            assert!(!text.starts_with('-') && !text.starts_with("+-"), "{d:?}: {text}");
        }
    }
}
