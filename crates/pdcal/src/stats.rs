//! Statistics of a series seen one value at a time, in memory that does not grow with its
//! length: mean and standard deviation from running sums, and an evenly thinned copy for
//! the figures. A long calibration's Sun-vector metrics go through them.

/// Running sums of finite values for the mean and the sample standard deviation. The
/// values are summed in arrival order, so the mean equals `sum / n` of the whole series
/// bit for bit; the squares are taken about the first value, which keeps the variance as
/// accurate as a two-pass sum for series whose spread is small against their level.
#[derive(Debug, Clone, Copy, Default)]
pub struct MeanStdSums {
    count: usize,
    sum: f64,
    shift: f64,
    sum_shifted: f64,
    sum_sq_shifted: f64,
}

impl MeanStdSums {
    /// Adds `x` (non-finite values are not counted).
    pub fn push(&mut self, x: f64) {
        if !x.is_finite() {
            return;
        }
        if self.count == 0 {
            self.shift = x;
        }
        let d = x - self.shift;
        self.count += 1;
        self.sum += x;
        self.sum_shifted += d;
        self.sum_sq_shifted += d * d;
    }

    /// Finite values counted.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Mean, NaN without values.
    pub fn mean(&self) -> f64 {
        self.sum / self.count as f64
    }

    /// Sample standard deviation, NaN with fewer than two values.
    pub fn std(&self) -> f64 {
        if self.count < 2 {
            return f64::NAN;
        }
        let n = self.count as f64;
        let var = (self.sum_sq_shifted - self.sum_shifted * self.sum_shifted / n) / (n - 1.0);
        var.max(0.0).sqrt()
    }
}

/// Every `stride`-th of the values pushed, at most `2 * cap` kept: when full, every other
/// kept value is dropped and the stride doubles, so the kept values stay evenly spread over
/// the whole series whatever its length. Up to `2 * cap` values, all are kept.
#[derive(Debug, Clone)]
pub struct Thinned<T> {
    kept: Vec<T>,
    stride: usize,
    seen: usize,
    cap: usize,
}

impl<T> Thinned<T> {
    /// Keeps at most `2 * cap` values (`cap` at least 1).
    pub fn new(cap: usize) -> Self {
        Thinned {
            kept: Vec::new(),
            stride: 1,
            seen: 0,
            cap: cap.max(1),
        }
    }

    /// Offers the next value of the series.
    pub fn push(&mut self, value: T) {
        if self.seen.is_multiple_of(self.stride) {
            if self.kept.len() == 2 * self.cap {
                let mut i = 0;
                self.kept.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if self.seen.is_multiple_of(self.stride) {
                self.kept.push(value);
            }
        }
        self.seen += 1;
    }

    /// The kept values, in series order.
    pub fn kept(&self) -> &[T] {
        &self.kept
    }

    /// Values offered.
    pub fn seen(&self) -> usize {
        self.seen
    }

    /// The kept values.
    pub fn into_kept(self) -> Vec<T> {
        self.kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_match_the_two_pass_mean_and_std() {
        // A series like the Sun-vector magnitudes: level 1, small spread, a NaN.
        let values: Vec<f64> = (0..10_000)
            .map(|i| 1.0 + 0.01 * ((i as f64) * 0.37).sin() + 1e-4 * (i % 7) as f64)
            .chain([f64::NAN])
            .collect();
        let mut sums = MeanStdSums::default();
        values.iter().for_each(|&x| sums.push(x));
        let finite: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        let n = finite.len() as f64;
        let mean = finite.iter().sum::<f64>() / n;
        let std = (finite.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert_eq!(sums.count(), finite.len());
        assert_eq!(sums.mean().to_bits(), mean.to_bits());
        assert!(
            (sums.std() - std).abs() <= 1e-12 * std,
            "{} {std}",
            sums.std()
        );
    }

    #[test]
    fn too_few_values_give_nan() {
        let mut sums = MeanStdSums::default();
        assert!(sums.mean().is_nan() && sums.std().is_nan());
        sums.push(2.0);
        assert_eq!(sums.mean(), 2.0);
        assert!(sums.std().is_nan());
    }

    #[test]
    fn thinned_keeps_all_up_to_twice_the_cap_then_an_even_stride() {
        let mut short = Thinned::new(5);
        (0..10).for_each(|i| short.push(i));
        assert_eq!(short.kept(), (0..10).collect::<Vec<_>>());
        let mut long = Thinned::new(5);
        (0..1000).for_each(|i| long.push(i));
        let kept = long.kept();
        assert!(kept.len() <= 10 && kept.len() >= 5, "{kept:?}");
        let stride = kept[1] - kept[0];
        assert!(kept.windows(2).all(|w| w[1] - w[0] == stride), "{kept:?}");
        assert_eq!(kept[0], 0);
        assert!(*kept.last().unwrap() + stride >= 1000, "{kept:?}");
        assert_eq!(long.seen(), 1000);
    }
}
