//! A derive's per-sample times, s since its first sample's time.
//!
//! The derive computes its times in f64 ([`TimeBase::Seconds`]); once stored, they are
//! whole nanoseconds from the first sample, read back as `ns as f64 * 1e-9`
//! ([`TimeBase::Nanos`]). The stored form keeps each time as a 32-bit offset from the
//! time of its block of [`NANOS_BLOCK`] samples: half the memory of an f64 per sample
//! (17 MB less at 12 h at 100 Hz), with every time given back bit for bit.

use std::sync::Arc;

/// Samples per block of [`NanoTimes`]: at 100 Hz a block spans 0.64 s, far inside a
/// 32-bit offset's 4.29 s, so only a gap in the log needs [`NanoTimes`]'s far list.
pub const NANOS_BLOCK: usize = 64;

/// Offset marking a sample whose time is in the far list.
const FAR: u32 = u32::MAX;

/// The largest |ns| whose time in seconds (`ns as f64 * 1e-9`, as a stored derive's times
/// are read) gives `ns` back when scaled by 1e9 and rounded to the nearest (6.5 days).
///
/// `ns` is exact in an f64 (below 2^53); `1e-9` is within a relative 2^-53 of 10^-9, and
/// the two products each round within a relative 2^-53, so the scaled value is within
/// |ns| · 3.0000001 · 2^-53 ≤ 0.19 of `ns`, and rounds to it.
pub const ROUND_TRIP_NS_MAX: i64 = 1 << 49;

/// Per-sample times.
#[derive(Clone)]
pub enum TimeBase {
    /// Seconds as computed (the derive's own times, before they are stored).
    Seconds(Arc<Vec<f64>>),
    /// Whole nanoseconds (as stored), compact.
    Nanos(Arc<NanoTimes>),
}

impl Default for TimeBase {
    fn default() -> Self {
        TimeBase::Seconds(Arc::default())
    }
}

impl std::fmt::Debug for TimeBase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self {
            TimeBase::Seconds(_) => "Seconds",
            TimeBase::Nanos(_) => "Nanos",
        };
        write!(
            f,
            "TimeBase::{kind}({} samples, {:?} .. {:?} s)",
            self.len(),
            self.first(),
            self.last()
        )
    }
}

/// Equal when every time is equal (whatever the form).
impl PartialEq for TimeBase {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len()
            && self
                .iter()
                .zip(other.iter())
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

impl From<Vec<f64>> for TimeBase {
    fn from(t_s: Vec<f64>) -> Self {
        TimeBase::Seconds(Arc::new(t_s))
    }
}

impl TimeBase {
    /// The stored form of whole nanoseconds since the first sample's time.
    /// Sized once from the iterator's lower size bound (exact for a [`Times`] or a slice).
    pub fn from_nanos(ns: impl IntoIterator<Item = i64>) -> Self {
        let ns = ns.into_iter();
        let mut b = NanoTimes::builder().with_room_for(ns.size_hint().0);
        for t in ns {
            b.push(t);
        }
        TimeBase::Nanos(Arc::new(b.finish()))
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            TimeBase::Seconds(t) => t.len(),
            TimeBase::Nanos(t) => t.len(),
        }
    }

    /// Whether there is no sample.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Time of sample `k`, s.
    ///
    /// # Panics
    /// If `k` is not below [`Self::len`].
    #[inline]
    pub fn get(&self, k: usize) -> f64 {
        match self {
            TimeBase::Seconds(t) => t[k],
            TimeBase::Nanos(t) => t.get(k),
        }
    }

    /// The first sample's time.
    pub fn first(&self) -> Option<f64> {
        (!self.is_empty()).then(|| self.get(0))
    }

    /// The last sample's time.
    pub fn last(&self) -> Option<f64> {
        self.len().checked_sub(1).map(|k| self.get(k))
    }

    /// The times of the samples `range`, in order.
    ///
    /// # Panics
    /// If the range goes past [`Self::len`].
    pub fn range(&self, range: std::ops::Range<usize>) -> Times<'_> {
        assert!(range.end <= self.len(), "{range:?} of {}", self.len());
        Times { base: self, range }
    }

    /// The stored whole nanoseconds since the first sample's time, when the times are
    /// stored as such ([`TimeBase::Nanos`]).
    pub fn nanos(&self) -> Option<&NanoTimes> {
        match self {
            TimeBase::Seconds(_) => None,
            TimeBase::Nanos(t) => Some(t),
        }
    }

    /// Every time, in order.
    pub fn iter(&self) -> Times<'_> {
        self.range(0..self.len())
    }

    /// The index of the first sample whose time fails `pred`, which holds for a prefix of
    /// the samples (as [`slice::partition_point`]).
    pub fn partition_point(&self, mut pred: impl FnMut(f64) -> bool) -> usize {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if pred(self.get(mid)) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// The times in a vector.
    pub fn to_vec(&self) -> Vec<f64> {
        self.iter().collect()
    }
}

/// [`TimeBase::range`].
#[derive(Clone)]
pub struct Times<'a> {
    base: &'a TimeBase,
    range: std::ops::Range<usize>,
}

impl Iterator for Times<'_> {
    type Item = f64;

    #[inline]
    fn next(&mut self) -> Option<f64> {
        let k = self.range.next()?;
        Some(self.base.get(k))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.range.size_hint()
    }
}

impl ExactSizeIterator for Times<'_> {}

/// Whole nanoseconds since the first sample's time, by blocks of [`NANOS_BLOCK`]
/// samples: each block's first time in full, each sample's offset from it in 32 bits,
/// and the times whose offset does not fit (across a gap of over 4.29 s, or before the
/// block's first) apart.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NanoTimes {
    block_ns: Vec<i64>,
    offset_ns: Vec<u32>,
    /// (sample, time) of the samples whose offset is [`FAR`], by sample.
    far: Vec<(usize, i64)>,
}

impl NanoTimes {
    /// An empty builder.
    pub fn builder() -> NanoTimesBuilder {
        NanoTimesBuilder(NanoTimes::default())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.offset_ns.len()
    }

    /// Whether there is no sample.
    pub fn is_empty(&self) -> bool {
        self.offset_ns.is_empty()
    }

    /// Time of sample `k`, ns.
    #[inline]
    pub fn ns(&self, k: usize) -> i64 {
        let o = self.offset_ns[k];
        if o != FAR {
            self.block_ns[k / NANOS_BLOCK] + i64::from(o)
        } else {
            let i = self.far.partition_point(|&(j, _)| j < k);
            self.far[i].1
        }
    }

    /// Time of sample `k`, s: `ns as f64 * 1e-9`, as a stored derive's times are read.
    #[inline]
    pub fn get(&self, k: usize) -> f64 {
        self.ns(k) as f64 * 1e-9
    }
}

/// Builds a [`NanoTimes`] sample by sample.
pub struct NanoTimesBuilder(NanoTimes);

impl NanoTimesBuilder {
    /// Room for `n` samples.
    pub fn with_room_for(mut self, n: usize) -> Self {
        self.0.offset_ns.reserve_exact(n);
        self.0.block_ns.reserve_exact(n.div_ceil(NANOS_BLOCK));
        self
    }

    /// The next sample's time, ns.
    pub fn push(&mut self, ns: i64) {
        let t = &mut self.0;
        let k = t.offset_ns.len();
        if k.is_multiple_of(NANOS_BLOCK) {
            t.block_ns.push(ns);
        }
        let base = t.block_ns[k / NANOS_BLOCK];
        match ns.checked_sub(base).and_then(|o| u32::try_from(o).ok()) {
            Some(o) if o != FAR => t.offset_ns.push(o),
            _ => {
                t.offset_ns.push(FAR);
                t.far.push((k, ns));
            }
        }
    }

    /// The times.
    pub fn finish(self) -> NanoTimes {
        self.0
    }
}

/// Time tags read in order (an ingested odometer's, ns in the log's time base): the first
/// in full, then each tag's step from the one before in 32 bits, and the steps that do
/// not fit (a gap of over 4.29 s, or a tag going back) in full, in order, beside them.
/// Half the memory of an i64 per tag at any rate, every tag given back exactly.
///
/// Every [`MARK_TAGS`] tags, a mark lets them be read from there ([`TagTimes::marks`])
/// with the tag before and the greatest of those before it: what a reader that keeps only
/// tags later than all before (the derive's odometer) needs to know whether it would keep
/// the tags there, without reading from the first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TagTimes {
    first_ns: i64,
    /// The last tag (where the next step starts).
    last_ns: i64,
    /// Each tag's step from the one before (the first's is 0).
    steps_ns: Vec<u32>,
    /// The tags whose step is [`FAR`], in order.
    far_ns: Vec<i64>,
    /// The greatest tag before the last one (`i64::MIN` before there are two).
    max_before_last_ns: i64,
    /// A mark at each tag whose index is a positive multiple of [`MARK_TAGS`].
    marks: Vec<TagMark>,
}

/// Tags between [`TagTimes`]' marks: a read from a mark reaches any tag within this many
/// (40 s at 100 Hz); 24 bytes a mark (25 kB at 12 h at 100 Hz).
pub const MARK_TAGS: usize = 4096;

/// Where [`TagTimes`]' tags can be read from at tag `MARK_TAGS × (i + 1)`, for mark `i`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TagMark {
    /// Tags in [`TagTimes::far_ns`] before the marked one.
    far: usize,
    /// The tag before the marked one, ns.
    before_ns: i64,
    /// The greatest of the tags before that one, ns.
    max_earlier_ns: i64,
}

/// A place in [`TagTimes`] to read its tags from ([`TagTimes::marks`]).
#[derive(Debug, Clone)]
pub struct TagsFrom<'a> {
    /// The index of the first tag read.
    pub index: usize,
    /// The tag before it, ns.
    pub before_ns: i64,
    /// The greatest of the tags before that one, ns (a mark's tag is never the first or
    /// second).
    pub max_earlier_ns: i64,
    /// The tags from `index` on.
    pub tags: TagIter<'a>,
}

impl TagTimes {
    /// No tag yet, with room for `n`.
    pub fn with_room_for(n: usize) -> Self {
        Self {
            steps_ns: Vec::with_capacity(n),
            marks: Vec::with_capacity(n / MARK_TAGS),
            ..Self::default()
        }
    }

    /// Appends the tags `ns`.
    pub fn extend(&mut self, ns: impl IntoIterator<Item = i64>) {
        let mut prev = (!self.is_empty()).then_some(self.last_ns);
        for t in ns {
            if let Some(p) = prev {
                let index = self.steps_ns.len();
                if index.is_multiple_of(MARK_TAGS) {
                    self.marks.push(TagMark {
                        far: self.far_ns.len(),
                        before_ns: p,
                        max_earlier_ns: self.max_before_last_ns,
                    });
                }
                self.max_before_last_ns = self.max_before_last_ns.max(p);
            } else {
                self.max_before_last_ns = i64::MIN;
            }
            let step = prev
                .and_then(|p| t.checked_sub(p))
                .and_then(|d| u32::try_from(d).ok())
                .filter(|&d| d != FAR);
            match (prev, step) {
                (None, _) => {
                    self.first_ns = t;
                    self.steps_ns.push(0);
                }
                (Some(_), Some(d)) => self.steps_ns.push(d),
                (Some(_), None) => {
                    self.steps_ns.push(FAR);
                    self.far_ns.push(t);
                }
            }
            prev = Some(t);
        }
        if let Some(last) = prev {
            self.last_ns = last;
        }
    }

    /// Number of tags.
    pub fn len(&self) -> usize {
        self.steps_ns.len()
    }

    /// Whether there is no tag.
    pub fn is_empty(&self) -> bool {
        self.steps_ns.is_empty()
    }

    /// The tags in order, ns.
    pub fn iter(&self) -> TagIter<'_> {
        TagIter {
            steps_ns: self.steps_ns.iter(),
            far_ns: self.far_ns.iter(),
            prev_ns: self.first_ns,
        }
    }

    /// The places the tags can be read from besides the first (every [`MARK_TAGS`]
    /// tags), in order.
    pub fn marks(&self) -> impl DoubleEndedIterator<Item = TagsFrom<'_>> + ExactSizeIterator {
        self.marks.iter().enumerate().map(|(i, m)| {
            let index = (i + 1) * MARK_TAGS;
            TagsFrom {
                index,
                before_ns: m.before_ns,
                max_earlier_ns: m.max_earlier_ns,
                tags: TagIter {
                    steps_ns: self.steps_ns[index..].iter(),
                    far_ns: self.far_ns[m.far..].iter(),
                    prev_ns: m.before_ns,
                },
            }
        })
    }
}

/// [`TagTimes::iter`].
#[derive(Debug, Clone)]
pub struct TagIter<'a> {
    steps_ns: std::slice::Iter<'a, u32>,
    far_ns: std::slice::Iter<'a, i64>,
    prev_ns: i64,
}

impl Iterator for TagIter<'_> {
    type Item = i64;

    #[inline]
    fn next(&mut self) -> Option<i64> {
        let step = *self.steps_ns.next()?;
        self.prev_ns = match step {
            FAR => *self.far_ns.next()?,
            _ => self.prev_ns + i64::from(step),
        };
        Some(self.prev_ns)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.steps_ns.size_hint()
    }
}

impl ExactSizeIterator for TagIter<'_> {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stored times of `ns` as a derive read them before: `ns as f64 * 1e-9` each.
    fn as_read(ns: &[i64]) -> Vec<u64> {
        ns.iter().map(|&t| (t as f64 * 1e-9).to_bits()).collect()
    }

    fn bits(t: &TimeBase) -> Vec<u64> {
        t.iter().map(f64::to_bits).collect()
    }

    #[test]
    fn tags_come_back_exactly_in_order() {
        // 100 Hz and 1 Hz stretches, a 6 s gap, a tag going back, repeated tags, the
        // extremes of i64 steps; appended in pieces.
        let mut ns: Vec<i64> = vec![-5_000_000_000, -4_990_000_000];
        let mut t = 1_000_000_000_i64;
        for k in 0..5000i64 {
            t += match k {
                100 => 6_000_000_000,
                200 => -30_000_000,
                300 | 301 => 0,
                1000..=1999 => 1_000_000_000,
                _ => 10_000_000 + (k * 7919) % 1000 - 500,
            };
            ns.push(t);
        }
        ns.extend([i64::MAX, i64::MIN, 0]);
        let mut tags = TagTimes::with_room_for(ns.len());
        tags.extend(ns[..7].iter().copied());
        tags.extend(ns[7..3000].iter().copied());
        tags.extend(ns[3000..].iter().copied());
        assert_eq!(tags.len(), ns.len());
        assert_eq!(tags.iter().len(), ns.len());
        assert_eq!(tags.iter().collect::<Vec<_>>(), ns);
        // The two gaps, the tag going back and the three steps from and to the extremes
        // only are kept in full: the 1 Hz stretch steps in 32 bits as well.
        assert_eq!(tags.far_ns.len(), 6, "{:?}", tags.far_ns);
        assert_eq!(tags.steps_ns.capacity(), ns.len());
        assert!(TagTimes::default().iter().next().is_none());
    }

    #[test]
    fn marks_read_the_tags_from_there_with_the_tag_before_and_the_greatest_earlier() {
        // 100 Hz with a tag going back far, a gap past 32 bits just before a mark, and
        // tags at i64's extremes (the greatest earlier then stays at the top); appended
        // in pieces that end before, at and after marks.
        let n = 5 * MARK_TAGS + 17;
        let mut ns: Vec<i64> = (0..n as i64).map(|i| i * 10_000_000).collect();
        ns[MARK_TAGS + 5] -= 1_000_000_000_000;
        ns[2 * MARK_TAGS - 1] += 30_000_000_000;
        ns[3 * MARK_TAGS - 2] = i64::MAX;
        ns[4 * MARK_TAGS] = i64::MIN;
        let mut tags = TagTimes::with_room_for(n);
        for piece in ns.chunks(MARK_TAGS - 1) {
            tags.extend(piece.iter().copied());
        }
        let mut whole = TagTimes::default();
        whole.extend(ns.iter().copied());
        assert_eq!(tags, whole);
        assert_eq!(tags.marks().len(), 5);
        for (j, m) in tags.marks().enumerate() {
            let c = (j + 1) * MARK_TAGS;
            assert_eq!(m.index, c);
            assert_eq!(m.before_ns, ns[c - 1]);
            assert_eq!(m.max_earlier_ns, ns[..c - 1].iter().copied().max().unwrap());
            assert_eq!(m.tags.len(), n - c);
            assert!(m.tags.eq(ns[c..].iter().copied()), "from tag {c}");
        }
        // No mark at the first tag, nor before a mark's tag is there.
        let mut short = TagTimes::default();
        short.extend(ns[..MARK_TAGS].iter().copied());
        assert_eq!(short.marks().len(), 0);
        short.extend([ns[MARK_TAGS]]);
        assert_eq!(short.marks().len(), 1);
    }

    #[test]
    fn nanos_give_every_time_back_bit_for_bit() {
        // 100 Hz with jitter, a 6 s gap (past a 32-bit offset), a 30 s one, repeated
        // times, a time going back (not in a derive, but any input is kept), 12 h in.
        let mut ns = Vec::new();
        let mut t: i64 = 0;
        for k in 0..10_000i64 {
            t += match k {
                500 => 6_000_000_000,
                501 => 30_000_000_000,
                700 | 701 => 0,
                900 => -25_000_000,
                _ => 10_000_000 + (k * 7919) % 1000 - 500,
            };
            ns.push(t + if k > 5000 { 43_200_000_000_000 } else { 0 });
        }
        let tb = TimeBase::from_nanos(ns.iter().copied());
        assert_eq!(bits(&tb), as_read(&ns));
        assert_eq!(tb.len(), ns.len());
        for k in [0, 1, 63, 64, 499, 500, 501, 502, 700, 900, 5000, 5001, 9999] {
            assert_eq!(tb.get(k).to_bits(), (ns[k] as f64 * 1e-9).to_bits(), "{k}");
        }
        let TimeBase::Nanos(n) = &tb else {
            unreachable!()
        };
        // The gaps, the time going back and the 12-h jump only: the rest is 4 bytes.
        assert!(n.far.len() < 200, "{}", n.far.len());
        assert_eq!(
            tb.range(499..503).map(f64::to_bits).collect::<Vec<_>>(),
            as_read(&ns[499..503])
        );
        assert_eq!(tb.last(), Some(ns[9999] as f64 * 1e-9));
        // Sized once: four bytes a sample, not a vector grown to twice its length.
        assert_eq!(n.offset_ns.capacity(), ns.len());
    }

    #[test]
    fn nanoseconds_within_the_bound_come_back_from_seconds() {
        use rand::{Rng, SeedableRng};
        let back = |ns: i64| crate::derive::ns_since(0, ns as f64 * 1e-9);
        let max = ROUND_TRIP_NS_MAX;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(49);
        let edges = [0, 1, -1, max, -max, max - 1, 1 << 40, 43_200_000_000_000];
        let random = (0..200_000).map(|_| rng.random_range(-max..=max));
        // Near the bound, where the round trip's error is largest.
        let near = (0..200_000).map(|k| max - k * 7_919);
        for ns in edges.into_iter().chain(random).chain(near) {
            assert_eq!(back(ns), ns, "{ns}");
        }
        // Far past it the trip loses nanoseconds: the bound is not idle.
        let lost = (0..1000i64)
            .map(|k| (1i64 << 62) + k * 1_000_003)
            .filter(|&ns| back(ns) != ns)
            .count();
        assert!(lost > 0);
    }

    #[test]
    fn forms_compare_by_value_and_search_as_slices_do() {
        let ns: Vec<i64> = (0..1000).map(|k| k * 10_000_000 + k % 3).collect();
        let secs: Vec<f64> = ns.iter().map(|&t| t as f64 * 1e-9).collect();
        let (a, b) = (TimeBase::from_nanos(ns), TimeBase::from(secs.clone()));
        assert_eq!(a, b);
        for x in [-1.0, 0.0, 0.005, 3.33, 9.99, 100.0] {
            assert_eq!(
                a.partition_point(|t| t < x),
                secs.partition_point(|&t| t < x)
            );
        }
        let mut c = secs;
        c[500] += 1e-12;
        assert_ne!(a, TimeBase::from(c));
        assert_eq!(TimeBase::default().first(), None);
        assert_eq!(TimeBase::from_nanos([]).last(), None);
    }
}
