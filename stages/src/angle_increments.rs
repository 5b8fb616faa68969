//! The IMU's angle increments as a derive holds them: in `f32` when every value converts
//! to `f32` and back unchanged (a binary log's counts times a power-of-two LSB, as the
//! UNZ format's 2⁻²⁶ rad), else in `f64`. Readers get the same `f64`s either way, bit
//! for bit: the compact form only drops bits that are zero.
//!
//! A 12-hour run at 100 Hz holds 4.32 M samples: 104 MB of angle increments in `f64`,
//! 52 MB in `f32`. The `f32`s are made in the `f64`s' own allocation, which then shrinks
//! to them: the two are never held side by side.

/// One sample's three increments as stored: `[f32; 3]` or `[f64; 3]`, read as `f64`s.
pub trait Increment3: Copy + Send + Sync + 'static {
    /// The increments, rad.
    fn rad(self) -> [f64; 3];
}

impl Increment3 for [f64; 3] {
    #[inline(always)]
    fn rad(self) -> [f64; 3] {
        self
    }
}

impl Increment3 for [f32; 3] {
    #[inline(always)]
    fn rad(self) -> [f64; 3] {
        self.map(f64::from)
    }
}

/// Whether `v` converts to `f32` and back to the very same bits.
#[inline(always)]
fn fits_f32(v: f64) -> bool {
    f64::from(v as f32).to_bits() == v.to_bits()
}

/// A run's angle increments per sample, rad, body FRD (see the module's doc).
#[derive(Debug, Clone)]
pub enum AngleIncrements {
    /// Every value exactly an `f32`.
    Single(PackedSingles),
    /// Some value not an `f32`.
    Double(Vec<[f64; 3]>),
}

/// `[f32; 3]`s packed in 8-byte words: the allocation of the `[f64; 3]`s they were
/// converted from, in place, then shrunk ([`AngleIncrements::compact`]).
#[derive(Debug, Clone, Default)]
pub struct PackedSingles {
    words: Vec<u64>,
    len: usize,
}

impl PackedSingles {
    /// `values`, every one of them exactly an `f32`, converted in their own allocation.
    fn in_place(values: Vec<[f64; 3]>) -> Self {
        let len = values.len();
        let mut words: Vec<u64> = bytemuck::cast_vec(values);
        let halves: &mut [u32] = bytemuck::cast_slice_mut(&mut words);
        // The j-th f32 goes to half j; the j-th f64 is read from halves 2j and 2j + 1,
        // never below a half already written (j ≤ 2j), and read before it is written.
        for j in 0..3 * len {
            let bits: u64 = bytemuck::cast([halves[2 * j], halves[2 * j + 1]]);
            halves[j] = (f64::from_bits(bits) as f32).to_bits();
        }
        words.truncate((3 * len).div_ceil(2));
        words.shrink_to_fit();
        Self { words, len }
    }

    /// Sets triple `k` (panics past the end).
    fn set(&mut self, k: usize, v: [f32; 3]) {
        let halves: &mut [u32] = bytemuck::cast_slice_mut(&mut self.words);
        halves[3 * k..3 * k + 3].copy_from_slice(&v.map(f32::to_bits));
    }

    /// The triples in `f64`, in their own allocation grown back (the growth of a large
    /// one remaps its pages: they are not held twice).
    fn widen(self) -> Vec<[f64; 3]> {
        let Self { mut words, len } = self;
        words.reserve_exact(3 * len - words.len());
        words.resize(3 * len, 0);
        let halves: &mut [u32] = bytemuck::cast_slice_mut(&mut words);
        // From the last: the j-th f64 goes to halves 2j and 2j + 1, above every f32 not
        // yet read (those below j), and the j-th f32 is read before it is written over.
        for j in (0..3 * len).rev() {
            let v = f64::from(f32::from_bits(halves[j]));
            let [a, b]: [u32; 2] = bytemuck::cast(v.to_bits());
            halves[2 * j] = a;
            halves[2 * j + 1] = b;
        }
        bytemuck::try_cast_vec(words)
            .unwrap_or_else(|(_, words)| bytemuck::cast_slice(&words).to_vec())
    }

    /// The triples.
    #[inline(always)]
    pub fn as_slice(&self) -> &[[f32; 3]] {
        let floats: &[f32] = bytemuck::cast_slice(&self.words);
        bytemuck::cast_slice(&floats[..3 * self.len])
    }
}

impl Default for AngleIncrements {
    fn default() -> Self {
        Self::Double(Vec::new())
    }
}

impl PartialEq for AngleIncrements {
    /// Equal values, whichever form holds them.
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.view().iter().eq(other.view().iter())
    }
}

impl From<Vec<[f64; 3]>> for AngleIncrements {
    fn from(values: Vec<[f64; 3]>) -> Self {
        Self::compact(values)
    }
}

impl FromIterator<[f64; 3]> for AngleIncrements {
    /// The values collected, then [`AngleIncrements::compact`]ed.
    fn from_iter<I: IntoIterator<Item = [f64; 3]>>(iter: I) -> Self {
        Self::compact(iter.into_iter().collect())
    }
}

impl AngleIncrements {
    /// `values` in `f32` when every one of them is exactly an `f32` (converted in their
    /// own allocation, which then shrinks to half), else as they are.
    pub fn compact(values: Vec<[f64; 3]>) -> Self {
        if all_fit_f32(bytemuck::cast_slice(&values)) {
            Self::Single(PackedSingles::in_place(values))
        } else {
            Self::Double(values)
        }
    }

    /// Sets sample `k`'s increments to `v` (panics past the end): held in `f64` from
    /// then on unless `v` is exactly in `f32` too (a gap's scaled increment is not).
    pub fn set(&mut self, k: usize, v: [f64; 3]) {
        match self {
            Self::Double(d) => d[k] = v,
            Self::Single(s) if v.iter().all(|&x| fits_f32(x)) => s.set(k, v.map(|x| x as f32)),
            Self::Single(_) => {
                let Self::Single(s) = std::mem::take(self) else {
                    unreachable!("matched as Single")
                };
                let mut d = s.widen();
                d[k] = v;
                *self = Self::Double(d);
            }
        }
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.view().len()
    }

    /// Whether no sample is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `k`'s increments, rad. Panics past the end, as indexing does.
    #[inline(always)]
    pub fn get(&self, k: usize) -> [f64; 3] {
        self.view().get(k)
    }

    /// The increments as a slice of either form.
    #[inline(always)]
    pub fn view(&self) -> AngleSlice<'_> {
        match self {
            Self::Single(v) => AngleSlice::Single(v.as_slice()),
            Self::Double(v) => AngleSlice::Double(v),
        }
    }

    /// Whether they are held in `f32`.
    pub fn is_single(&self) -> bool {
        matches!(self, Self::Single(_))
    }

    /// Bytes of room the values' allocation holds.
    #[cfg(test)]
    fn room_bytes(&self) -> usize {
        match self {
            Self::Single(v) => v.words.capacity() * std::mem::size_of::<u64>(),
            Self::Double(v) => v.capacity() * std::mem::size_of::<[f64; 3]>(),
        }
    }

    /// Bytes the values take (their room aside).
    #[cfg(test)]
    fn held_bytes(&self) -> usize {
        match self.view() {
            AngleSlice::Single(v) => std::mem::size_of_val(v),
            AngleSlice::Double(v) => std::mem::size_of_val(v),
        }
    }
}

/// [`AngleIncrements`] gathered as a reader hands their values over, a page at a time:
/// in `f32` while every value so far is one exactly, so that a binary log's increments
/// never take the `f64`s' bytes (a load that compacted them afterwards first filled
/// twice the memory, 5.8 MB more pages touched in a 40-minute disupt process). The first
/// value that is not an `f32` turns what is held into `f64`s, and the rest follow as
/// they come.
#[derive(Debug)]
pub struct AngleIncrementsBuilder {
    /// Samples to make room for when the first values come.
    room: usize,
    form: Building,
}

/// What an [`AngleIncrementsBuilder`] holds so far.
#[derive(Debug)]
enum Building {
    /// The values in `f32`, two a word; `floats` of them, the last word's second half
    /// unused when it is odd.
    Single { words: Vec<u64>, floats: usize },
    /// The values in `f64`.
    Double(Vec<f64>),
}

impl AngleIncrementsBuilder {
    /// A builder that takes room for `samples` samples (three values each) when its
    /// first values come, in the form they take: the caller's bound, which more values
    /// than it grow past.
    pub fn with_room_for(samples: usize) -> Self {
        Self {
            room: samples,
            form: Building::Single {
                words: Vec::new(),
                floats: 0,
            },
        }
    }

    /// The next values, in order: three a sample, a sample's values possibly split
    /// between two calls.
    pub fn extend_from_values(&mut self, values: &[f64]) {
        if values.is_empty() {
            return;
        }
        let room_values = 3 * self.room;
        if let Building::Single { words, floats } = &mut self.form {
            if all_fit_f32(values) {
                if words.capacity() == 0 {
                    words.reserve_exact(room_values.div_ceil(2));
                }
                push_singles(words, floats, values);
                return;
            }
            let mut doubles = Vec::with_capacity(room_values.max(*floats + values.len()));
            let halves: &[u32] = bytemuck::cast_slice(words);
            doubles.extend(
                halves[..*floats]
                    .iter()
                    .map(|&h| f64::from(f32::from_bits(h))),
            );
            self.form = Building::Double(doubles);
        }
        if let Building::Double(doubles) = &mut self.form {
            doubles.extend_from_slice(values);
        }
    }

    /// The increments, or `None` when the values do not make whole samples.
    pub fn finish(self) -> Option<AngleIncrements> {
        match self.form {
            Building::Single { mut words, floats } => {
                if floats % 3 != 0 {
                    return None;
                }
                words.shrink_to_fit();
                Some(AngleIncrements::Single(PackedSingles {
                    words,
                    len: floats / 3,
                }))
            }
            Building::Double(mut doubles) => {
                if doubles.len() % 3 != 0 {
                    return None;
                }
                doubles.shrink_to_fit();
                let rows = bytemuck::try_cast_vec(doubles).unwrap_or_else(|(_, doubles)| {
                    bytemuck::cast_slice::<f64, [f64; 3]>(&doubles).to_vec()
                });
                Some(AngleIncrements::Double(rows))
            }
        }
    }
}

/// Whether every one of `values` is exactly an `f32` (a chunk at a time, each checked
/// whole: a loop the compiler vectorises).
fn all_fit_f32(values: &[f64]) -> bool {
    values
        .chunks(1024)
        .all(|c| c.iter().fold(true, |ok, &v| ok & fits_f32(v)))
}

/// Appends `values` (each exactly an `f32`) to the `floats` `f32`s held two a word in
/// `words`.
fn push_singles(words: &mut Vec<u64>, floats: &mut usize, values: &[f64]) {
    let mut rest = values;
    if *floats % 2 == 1 {
        // The last word's second half.
        let last = words.last_mut().expect("an odd count has a last word");
        let [low, _]: [u32; 2] = bytemuck::cast(*last);
        *last = bytemuck::cast([low, (rest[0] as f32).to_bits()]);
        rest = &rest[1..];
    }
    let pairs = rest.chunks_exact(2);
    let odd = pairs.remainder();
    words.extend(pairs.map(|p| {
        bytemuck::cast::<[u32; 2], u64>([(p[0] as f32).to_bits(), (p[1] as f32).to_bits()])
    }));
    if let [v] = odd {
        words.push(bytemuck::cast([(*v as f32).to_bits(), 0u32]));
    }
    *floats += values.len();
}

/// A run's angle increments, or some of them, in the form they are held in
/// ([`AngleIncrements`]); read as `f64`s.
#[derive(Debug, Clone, Copy)]
pub enum AngleSlice<'a> {
    /// Held in `f32`.
    Single(&'a [[f32; 3]]),
    /// Held in `f64`.
    Double(&'a [[f64; 3]]),
}

impl<'a> From<&'a [[f64; 3]]> for AngleSlice<'a> {
    fn from(v: &'a [[f64; 3]]) -> Self {
        Self::Double(v)
    }
}

impl<'a> From<&'a Vec<[f64; 3]>> for AngleSlice<'a> {
    fn from(v: &'a Vec<[f64; 3]>) -> Self {
        Self::Double(v)
    }
}

/// Runs `$body` with `$s` bound to the slice `$view` holds, of `[f32; 3]` or `[f64; 3]`
/// (each [`Increment3`]): a kernel generic in the sample's form, compiled for each.
#[macro_export]
macro_rules! with_angle_slice {
    ($view:expr, |$s:ident| $body:expr) => {
        match $view {
            $crate::angle_increments::AngleSlice::Single($s) => $body,
            $crate::angle_increments::AngleSlice::Double($s) => $body,
        }
    };
}

impl<'a> AngleSlice<'a> {
    /// Samples in the slice.
    #[inline(always)]
    pub fn len(&self) -> usize {
        match self {
            Self::Single(v) => v.len(),
            Self::Double(v) => v.len(),
        }
    }

    /// Whether the slice is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `k`'s increments, rad. Panics past the end, as indexing does.
    #[inline(always)]
    pub fn get(&self, k: usize) -> [f64; 3] {
        match self {
            Self::Single(v) => v[k].rad(),
            Self::Double(v) => v[k],
        }
    }

    /// Sample `k`'s increments, if there is one.
    pub fn get_checked(&self, k: usize) -> Option<[f64; 3]> {
        (k < self.len()).then(|| self.get(k))
    }

    /// The samples `range` (panics out of bounds, as slicing does).
    pub fn slice(&self, range: std::ops::Range<usize>) -> AngleSlice<'a> {
        match *self {
            Self::Single(v) => Self::Single(&v[range]),
            Self::Double(v) => Self::Double(&v[range]),
        }
    }

    /// The first `n` samples (panics past the end).
    pub fn prefix(&self, n: usize) -> AngleSlice<'a> {
        self.slice(0..n)
    }

    /// Whether `other` is the very same memory (not an equal copy).
    pub fn same_as(&self, other: &AngleSlice<'_>) -> bool {
        let same_form = matches!(
            (self, other),
            (Self::Single(_), AngleSlice::Single(_)) | (Self::Double(_), AngleSlice::Double(_))
        );
        same_form && self.addr() == other.addr() && self.len() == other.len()
    }

    /// The first sample's address, for a slice's identity.
    pub fn addr(&self) -> usize {
        match self {
            Self::Single(v) => v.as_ptr() as usize,
            Self::Double(v) => v.as_ptr() as usize,
        }
    }

    /// The increments in order, rad.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = [f64; 3]> + 'a {
        let s = *self;
        (0..s.len()).map(move |k| s.get(k))
    }

    /// The increments as `f64`s, copied.
    pub fn to_vec(&self) -> Vec<[f64; 3]> {
        self.iter().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts times a power-of-two LSB are held in f32 and read back bit for bit; one
    /// value that is not an f32 keeps them all in f64.
    #[test]
    fn a_binary_logs_increments_are_held_in_half_the_bytes_and_read_the_same() {
        let lsb = (-26f64).exp2();
        let counts = [0i32, 1, -1, 671_088, -(1 << 23), (1 << 24) - 1, 12_345];
        let values: Vec<[f64; 3]> = counts
            .iter()
            .map(|&c| [c as f64 * lsb, -(c as f64) * lsb, -0.0])
            .collect();
        let held = AngleIncrements::compact(values.clone());
        assert!(held.is_single());
        assert_eq!(
            held.held_bytes() * 2,
            std::mem::size_of_val(values.as_slice())
        );
        for (k, v) in values.iter().enumerate() {
            assert_eq!(held.get(k).map(f64::to_bits), v.map(f64::to_bits));
        }
        let mut odd = values.clone();
        // A gap's scaled increment: not an f32.
        odd[3][1] *= 1.0 + 1e-12;
        let held = AngleIncrements::compact(odd.clone());
        assert!(!held.is_single());
        assert_eq!(held.view().to_vec(), odd);
        // A count beyond f32's 24 bits is not either.
        let wide = AngleIncrements::compact(vec![[((1 << 24) + 1) as f64 * lsb, 0.0, 0.0]]);
        assert!(!wide.is_single());
    }

    /// The f32s are made in the f64s' allocation, which then shrinks: the heap never holds
    /// the two at once (made apart, it held 1.5 times the f64s), and keeps half.
    #[test]
    fn compacting_holds_the_f64s_alone_and_keeps_half() {
        let n = 100_001;
        let lsb = (-26f64).exp2();
        let value = |k: usize| {
            let c = (k as f64 * 7.0) % 1e6 - 5e5;
            [c * lsb, -c * lsb, (c + 1.0) * lsb]
        };
        let (held, peak) = crate::counted_heap::peak_heap_bytes(1, || {
            let values: Vec<[f64; 3]> = (0..n).map(value).collect();
            AngleIncrements::compact(values)
        });
        assert!(held.is_single());
        let f64_bytes = n * 24;
        assert!(
            peak + (64 << 10) >= f64_bytes && peak < f64_bytes + f64_bytes / 20,
            "{peak} B at most for {f64_bytes} B of f64s"
        );
        assert!(
            held.room_bytes() <= n * 12 + 8,
            "{} B of room",
            held.room_bytes()
        );
        assert!((0..n).all(|k| held.get(k) == value(k)));
    }

    /// A value set that is an f32 keeps the f32s; one that is not turns them into the
    /// f64s they stand for, bit for bit, with it.
    #[test]
    fn a_value_set_keeps_the_form_when_it_can() {
        let lsb = (-26f64).exp2();
        for n in [1usize, 2, 3, 1000, 1001] {
            let values: Vec<[f64; 3]> = (0..n)
                .map(|k| [k as f64 * lsb, -(k as f64) * 3.0 * lsb, 0.5])
                .collect();
            let mut held = AngleIncrements::compact(values.clone());
            let mut want = values.clone();
            held.set(n / 2, [lsb, 2.0 * lsb, -lsb]);
            want[n / 2] = [lsb, 2.0 * lsb, -lsb];
            assert!(held.is_single());
            assert_eq!(held.view().to_vec(), want);
            let scaled = [1.5 * lsb * (1.0 + 1e-9), 0.0, 0.1];
            held.set(n - 1, scaled);
            want[n - 1] = scaled;
            assert!(!held.is_single());
            let bits =
                |v: Vec<[f64; 3]>| v.concat().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(held.view().to_vec()), bits(want.clone()));
            assert_eq!(held.room_bytes(), n * 24, "room for {n}");
        }
    }

    /// Equal values are equal whichever form holds them; slices keep their identity.
    #[test]
    fn forms_compare_by_value_and_slices_by_memory() {
        let values = vec![[0.25, -0.5, 1.0], [2.0, 0.0, -4.0]];
        let single = AngleIncrements::compact(values.clone());
        let double = AngleIncrements::Double(values.clone());
        assert!(single.is_single());
        assert_eq!(single, double);
        assert_ne!(single, AngleIncrements::Double(vec![[0.25, -0.5, 1.0]]));
        let (a, b) = (single.view(), single.view());
        assert!(a.same_as(&b) && !a.same_as(&double.view()));
        assert_eq!(a.slice(1..2).get(0), [2.0, 0.0, -4.0]);
        assert_eq!(a.get_checked(2), None);
    }

    /// `values` handed to a builder in pieces cut at `cuts` (indices of values, rising).
    fn built(values: &[f64], room: usize, cuts: &[usize]) -> Option<AngleIncrements> {
        let mut b = AngleIncrementsBuilder::with_room_for(room);
        let mut from = 0;
        for &to in cuts.iter().chain([&values.len()]) {
            b.extend_from_values(&values[from..to]);
            from = to;
        }
        b.finish()
    }

    /// A binary log's values handed over page by page, cut anywhere (mid-sample, mid-word),
    /// are held in f32 and read back as the compacted f64s, bit for bit, in no more heap
    /// than the f32s' (compacting the f64s afterwards held the f64s first).
    #[test]
    fn a_builder_holds_exact_values_in_f32_as_they_come() {
        let n = 100_001;
        let lsb = (-26f64).exp2();
        let values: Vec<f64> = (0..3 * n)
            .map(|i| ((i as f64 * 7.0) % 1e6 - 5e5) * lsb)
            .collect();
        let rows: Vec<[f64; 3]> = bytemuck::cast_slice(&values).to_vec();
        let expected = AngleIncrements::compact(rows.clone());
        assert!(expected.is_single());
        let cuts = [1, 2, 5, 8192, 8193, 100_000, 200_001, 299_999];
        let (held, peak) =
            crate::counted_heap::peak_heap_bytes(1, || built(&values, n, &cuts).unwrap());
        assert!(held.is_single());
        assert!((0..n).all(|k| held.get(k).map(f64::to_bits) == rows[k].map(f64::to_bits)));
        assert_eq!(held, expected);
        let f32_bytes = n * 12;
        // (Within 64 KiB: the measurement's pool holds a few blocks of its own.)
        assert!(
            peak <= f32_bytes + (64 << 10),
            "{peak} B held for {f32_bytes} B of f32s"
        );
        assert!(held.room_bytes() <= f32_bytes + 8);
        // Room asked for too small, or none: grown as it fills, the same values.
        assert_eq!(built(&values, 10, &cuts).unwrap(), expected);
        assert_eq!(built(&values, 0, &[]).unwrap(), expected);
    }

    /// A value that is not an f32, in any piece, turns what was held into the f64s it
    /// stood for, bit for bit, and the values after it follow in f64.
    #[test]
    fn a_builder_turns_to_f64_at_the_first_value_not_an_f32() {
        let lsb = (-26f64).exp2();
        let n = 5000;
        for odd_at in [0usize, 1, 2, 3, 7_777, 3 * n - 1] {
            let mut values: Vec<f64> = (0..3 * n).map(|i| (i as f64 - 4000.0) * lsb).collect();
            values[odd_at] = 0.1;
            let held = built(&values, n, &[3, 4, 7_000, 7_777, 10_001]).unwrap();
            assert!(!held.is_single(), "{odd_at}");
            let rows: Vec<[f64; 3]> = bytemuck::cast_slice(&values).to_vec();
            assert!(
                (0..n).all(|k| held.get(k).map(f64::to_bits) == rows[k].map(f64::to_bits)),
                "{odd_at}"
            );
        }
    }

    /// Values that do not make whole samples give no increments, in either form; none at
    /// all give none.
    #[test]
    fn a_builder_refuses_a_sample_left_open() {
        assert!(built(&[1.0, 2.0], 1, &[]).is_none());
        assert!(built(&[1.0, 2.0, 3.0, 4.0], 2, &[1]).is_none());
        assert!(built(&[0.1, 2.0, 3.0, 4.0], 2, &[]).is_none());
        let none = built(&[], 0, &[]).unwrap();
        assert!(none.is_empty());
    }
}
