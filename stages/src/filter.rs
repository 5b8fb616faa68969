//! The low-pass filter F shared by the accelerometer terms and the gyro pitch/roll they
//! are compared with (method.md: one and the same filter, so both carry the same delay).
//!
//! F = block means over `block` samples (0.1 s at 100 Hz; 1 sample at 10 Hz), then a
//! zero-phase (forward–backward) second-order Butterworth low-pass at `cutoff_hz` on the
//! block series. Zero phase means no delay at all: this is post-processing. Being linear,
//! F commutes with differencing, so `F(u̇)` equals the derivative of the filtered speed
//! and odometer pulse quantisation is suppressed as (2πf)² allows.

/// Second-order Butterworth low-pass biquad coefficients (bilinear transform).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    /// Low-pass at `cutoff_hz` for a series sampled at `rate_hz`.
    pub fn butterworth_lowpass(cutoff_hz: f64, rate_hz: f64) -> Self {
        let k = (std::f64::consts::PI * (cutoff_hz / rate_hz).min(0.49)).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Self {
            b: [b0, 2.0 * b0, b0],
            a: [2.0 * (k * k - 1.0) * norm, (1.0 - k / q + k * k) * norm],
        }
    }

    /// Filters `x` in place, forward then backward, starting from steady state on the
    /// first (resp. last) value so the ends do not ring.
    pub fn filtfilt(&self, x: &mut [f64]) {
        self.filtfilt_together([x]);
    }

    /// [`Self::filtfilt`] of each of `xs`, side by side in fours where their lengths
    /// agree: the recursions of four series overlap in the CPU where one alone waits on
    /// its own (the same operations on each series: bit for bit each alone).
    pub fn filtfilt_each(&self, xs: &mut [&mut [f64]]) {
        let mut rest = xs;
        while !rest.is_empty() {
            let len = rest[0].len();
            let same = rest.iter().take(4).take_while(|x| x.len() == len).count();
            let (group, tail) = rest.split_at_mut(same);
            match group {
                [a, b, c, d] => self.filtfilt_together([&mut **a, &mut **b, &mut **c, &mut **d]),
                [a, b, c] => self.filtfilt_together([&mut **a, &mut **b, &mut **c]),
                [a, b] => self.filtfilt_together([&mut **a, &mut **b]),
                [a] => self.filtfilt_together([&mut **a]),
                _ => unreachable!("one to four series at a time"),
            }
            rest = tail;
        }
    }

    /// [`Self::filtfilt`] of `K` series of one length, step by step together (in vector
    /// lanes where the CPU has AVX2).
    fn filtfilt_together<const K: usize>(&self, mut xs: [&mut [f64]; K]) {
        #[cfg(target_arch = "x86_64")]
        if K > 1 && std::arch::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: `filtfilt_avx2` only needs AVX2, and this CPU has it (checked above).
            return unsafe { self.filtfilt_avx2(&mut xs) };
        }
        self.filtfilt_portable(&mut xs);
    }

    /// [`Self::filtfilt_portable`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn filtfilt_avx2<const K: usize>(&self, xs: &mut [&mut [f64]; K]) {
        self.filtfilt_portable(xs);
    }

    #[inline(always)]
    fn filtfilt_portable<const K: usize>(&self, xs: &mut [&mut [f64]; K]) {
        let n = xs[0].len();
        assert!(
            xs.iter().all(|x| x.len() == n),
            "series of several lengths together"
        );
        self.pass_together(xs, 0..n);
        self.pass_together(xs, (0..n).rev());
    }

    /// One pass of the recursion over the samples `order` of each of `xs`, from steady
    /// state on the first sample taken: the series side by side (each lane's operations
    /// in the same order as one series alone).
    #[inline(always)]
    fn pass_together<const K: usize>(
        &self,
        xs: &mut [&mut [f64]; K],
        mut order: impl Iterator<Item = usize>,
    ) {
        let [b0, b1, b2] = self.b;
        let [a0, a1] = self.a;
        let Some(first) = order.next() else {
            return;
        };
        let v: [f64; K] = std::array::from_fn(|l| xs[l][first]);
        // x1, x2, y1, y2 of each series, from steady state on its first value.
        let (mut x1, mut x2, mut y1, mut y2) = (v, v, v, v);
        for i in std::iter::once(first).chain(order) {
            let v: [f64; K] = std::array::from_fn(|l| xs[l][i]);
            let y: [f64; K] = std::array::from_fn(|l| {
                b0 * v[l] + b1 * x1[l] + b2 * x2[l] - a0 * y1[l] - a1 * y2[l]
            });
            (x2, x1, y2, y1) = (x1, v, y1, y);
            for (x, y) in xs.iter_mut().zip(y) {
                x[i] = y;
            }
        }
    }
}

/// Parameters of F.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterParams {
    /// Length of the block means, s (0.1 s).
    pub block_s: f64,
    /// Butterworth cut-off, Hz (0.3 Hz).
    pub cutoff_hz: f64,
}

impl Default for FilterParams {
    fn default() -> Self {
        Self {
            block_s: 0.1,
            cutoff_hz: 0.3,
        }
    }
}

impl FilterParams {
    /// Seconds over which a pass's start-up dies away to a thousandth, s (5.2 s at
    /// 0.3 Hz): the second-order Butterworth's envelope falls as e^(−2π·f_c·t/√2). The
    /// forward pass starts from steady state on a series' first value, whose own noise
    /// (an odometer's pulses, in a block's u̇, at a log begun while driving) F does not
    /// average: the first seconds of the filtered series carry it.
    pub fn settling_s(&self) -> f64 {
        1000f64.ln() * std::f64::consts::SQRT_2 / (std::f64::consts::TAU * self.cutoff_hz)
    }
}

/// F, ready for a series of a given sample period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass {
    /// Samples per block.
    pub block: usize,
    biquad: Biquad,
}

impl LowPass {
    /// F for samples `dt_s` apart.
    pub fn new(params: &FilterParams, dt_s: f64) -> Self {
        let block = ((params.block_s / dt_s).round() as usize).max(1);
        let block_rate_hz = 1.0 / (block as f64 * dt_s);
        Self {
            block,
            biquad: Biquad::butterworth_lowpass(params.cutoff_hz, block_rate_hz),
        }
    }

    /// Number of blocks of a series of `n` samples (the last partial block included).
    pub fn blocks(&self, n: usize) -> usize {
        n.div_ceil(self.block)
    }

    /// Block means of `x` into `out` (replaced), then filtered.
    pub fn apply(&self, x: &[f64], out: &mut Vec<f64>) {
        *out = self.block_means(x.iter().copied());
        self.biquad.filtfilt(out);
    }

    /// Block means of the series `x` (unfiltered), taken as its values come: what
    /// [`LowPass::apply`] filters, without the series held whole.
    pub fn block_means(&self, x: impl Iterator<Item = f64>) -> Vec<f64> {
        let [means] = self.block_means_of(x.map(|v| [v]));
        means
    }

    /// [`LowPass::block_means`] of `N` series whose values come together.
    pub fn block_means_of<const N: usize>(
        &self,
        x: impl Iterator<Item = [f64; N]>,
    ) -> [Vec<f64>; N] {
        let mut means = BlockMeans::new(self.block, self.blocks(x.size_hint().0));
        for v in x {
            means.push(v);
        }
        means.finish()
    }

    /// Filters a series already reduced to block means.
    pub fn filter_blocks(&self, blocks: &mut [f64]) {
        self.biquad.filtfilt(blocks);
    }

    /// [`Self::filter_blocks`] of each of `series`, several side by side (bit for bit each
    /// alone: [`Biquad::filtfilt_each`]).
    pub fn filter_blocks_each(&self, series: &mut [&mut [f64]]) {
        self.biquad.filtfilt_each(series);
    }
}

/// Block means of `N` series whose values come together, taken as they come: running
/// sums from −0.0 in the values' order, so that each mean is what `Iterator::sum` of its
/// block's values over their count gives, bit for bit.
#[derive(Debug, Clone)]
pub struct BlockMeans<const N: usize> {
    block: usize,
    sums: [f64; N],
    count: usize,
    means: [Vec<f64>; N],
}

impl<const N: usize> BlockMeans<N> {
    /// Means over blocks of `block` values (at least one), with room for `blocks` of them.
    pub fn new(block: usize, blocks: usize) -> Self {
        Self {
            block: block.max(1),
            sums: [-0.0; N],
            count: 0,
            means: std::array::from_fn(|_| Vec::with_capacity(blocks)),
        }
    }

    /// The next values.
    #[inline]
    pub fn push(&mut self, v: [f64; N]) {
        for (sum, v) in self.sums.iter_mut().zip(v) {
            *sum += v;
        }
        self.count += 1;
        if self.count == self.block {
            self.close();
        }
    }

    fn close(&mut self) {
        for (means, sum) in self.means.iter_mut().zip(self.sums.iter_mut()) {
            means.push(*sum / self.count as f64);
            *sum = -0.0;
        }
        self.count = 0;
    }

    /// The means, the last (shorter) block's included.
    pub fn finish(mut self) -> [Vec<f64>; N] {
        if self.count > 0 {
            self.close();
        }
        self.means
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_dc_and_low_frequencies_without_delay() {
        let lp = LowPass::new(&FilterParams::default(), 0.01);
        assert_eq!(lp.block, 10);
        let x: Vec<f64> = (0..20_000)
            .map(|k| 3.0 + (k as f64 * 0.01 * 0.02 * std::f64::consts::TAU).sin())
            .collect();
        let mut y = Vec::new();
        lp.apply(&x, &mut y);
        // A 0.02 Hz sine passes with gain ≈ 1 and no phase shift (zero-phase filter).
        for (j, v) in y.iter().enumerate().skip(100).take(1800) {
            let t_mid = (j as f64 * 10.0 + 4.5) * 0.01;
            let want = 3.0 + (t_mid * 0.02 * std::f64::consts::TAU).sin();
            assert!((v - want).abs() < 2e-3, "block {j}: {v} vs {want}");
        }
    }

    /// The recursion written out for one series, as the filter's definition reads.
    fn filtfilt_by_hand(f: &Biquad, x: &[f64]) -> Vec<f64> {
        let [b0, b1, b2] = f.b;
        let [a0, a1] = f.a;
        let pass = |x: &[f64]| -> Vec<f64> {
            let Some(&x0) = x.first() else {
                return Vec::new();
            };
            let (mut x1, mut x2, mut y1, mut y2) = (x0, x0, x0, x0);
            x.iter()
                .map(|&v| {
                    let y = b0 * v + b1 * x1 + b2 * x2 - a0 * y1 - a1 * y2;
                    (x2, x1, y2, y1) = (x1, v, y1, y);
                    y
                })
                .collect()
        };
        let forward = pass(x);
        let mut back: Vec<f64> = forward.into_iter().rev().collect();
        back = pass(&back);
        back.reverse();
        back
    }

    /// Series filtered one to four at a time (in vector lanes or not) are what the
    /// recursion written out gives, bit for bit: lengths none, one, two and more.
    #[test]
    fn series_filtered_together_are_the_recursion_bit_for_bit() {
        let f = Biquad::butterworth_lowpass(0.3, 10.0);
        for lens in [
            vec![700, 700, 700, 700, 700, 700, 700, 0, 1, 2, 2],
            vec![5, 5, 5, 9],
            vec![1, 1, 1, 1],
        ] {
            let series: Vec<Vec<f64>> = lens
                .iter()
                .enumerate()
                .map(|(s, &n)| {
                    (0..n)
                        .map(|k| ((k * (s + 3)) as f64 * 0.21).sin() * 3.0 + 0.1 * s as f64)
                        .collect()
                })
                .collect();
            let mut together = series.clone();
            let mut refs: Vec<&mut [f64]> = together.iter_mut().map(|v| v.as_mut_slice()).collect();
            f.filtfilt_each(&mut refs);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            for (x, got) in series.iter().zip(&together) {
                assert_eq!(bits(got), bits(&filtfilt_by_hand(&f, x)), "{lens:?}");
                let mut alone = x.clone();
                f.filtfilt(&mut alone);
                assert_eq!(bits(&alone), bits(got), "{lens:?}");
            }
        }
    }

    #[test]
    fn series_filtered_side_by_side_are_each_alone_bit_for_bit() {
        let lp = LowPass::new(&FilterParams::default(), 0.01);
        let series: Vec<Vec<f64>> = (0..7)
            .map(|s| {
                let n = if s == 5 { 900 } else { 1000 };
                (0..n)
                    .map(|k| ((k * (s + 3)) as f64 * 0.013).sin() + 0.1 * s as f64)
                    .collect()
            })
            .collect();
        let mut together = series.clone();
        let mut refs: Vec<&mut [f64]> = together.iter_mut().map(|v| v.as_mut_slice()).collect();
        lp.filter_blocks_each(&mut refs);
        for (alone, got) in series.into_iter().zip(&together) {
            let mut alone = alone;
            lp.filter_blocks(&mut alone);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&alone), bits(got));
        }
    }

    #[test]
    fn suppresses_high_frequencies() {
        let lp = LowPass::new(&FilterParams::default(), 0.01);
        let x: Vec<f64> = (0..20_000)
            .map(|k| (k as f64 * 0.01 * 3.0 * std::f64::consts::TAU).sin())
            .collect();
        let mut y = Vec::new();
        lp.apply(&x, &mut y);
        let peak = y[200..1800].iter().fold(0f64, |m, v| m.max(v.abs()));
        // Fourth-order effective roll-off: (0.3/3)^4 ≈ 1e-4, and the block mean helps too.
        assert!(peak < 1e-3, "{peak}");
    }
}
