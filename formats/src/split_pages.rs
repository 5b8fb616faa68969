//! Float columns without nulls (flat, or in lists of a fixed length) written as
//! BYTE_STREAM_SPLIT pages: the pages, the chunk and its metadata parquet-rs's column
//! writer makes with the tables' settings, byte for byte, in a fraction of its time.
//!
//! The crate's writer copies every value into its encoder, finds the bounds of each batch
//! of 1 024 values one value at a time (a NaN test and two comparisons, each dispatched on
//! the column's type), encodes a list's levels one at a time, splits each page's bytes
//! into streams one byte at a time (a bounds check on each), and copies the compressed
//! page twice more. Here a page's values are split straight from the caller's array when
//! a page lies within it (else from the values kept since the last page), sixteen at a
//! time by SSE2's byte unpacking (the inverse of [`crate::split_doubles`]' join); the
//! bounds are kept in eight lanes; a list's levels, which depend on a page's count of
//! values only, are encoded once per count (by a port of the crate's RLE encoder, or
//! for the tables' lists, rows of up to eight values, by what that port writes for them,
//! without going through the values: tested against it); the
//! pages are split and compressed in buffers and by a zstd context the thread keeps (the
//! same library and level: the same bytes).
//!
//! What stays the crate's: where pages are cut (after each batch of `write_batch_size`
//! values carried to a row's end, once the page holds `data_page_row_count_limit` rows
//! or `data_page_size_limit` bytes of values), each page's header and offset in the
//! chunk, the chunk's metadata, histograms and offset index, all built by its public
//! types. Only the settings the tables use are taken ([`SplitColumn::new`]); any other
//! column goes to the crate's writer. `parquet_io`'s tests compare whole files with
//! `ArrowWriter`'s.

use std::sync::{Mutex, OnceLock};

use arrow::array::{ArrayRef, AsArray};
use arrow::datatypes::{ArrowNativeType, ArrowPrimitiveType, Float32Type, Float64Type};
use bytes::Bytes;
use parquet::basic::Encoding;
use parquet::column::writer::ColumnCloseResult;
use parquet::errors::ParquetError;
use parquet::file::properties::WriterPropertiesPtr;
use parquet::file::statistics::{Statistics, ValueStatistics};
use parquet::schema::types::ColumnDescPtr;

use crate::chunk_ledger::{ChunkLedger, PageSettings};
use crate::parquet_columns::{ChunkPages, DirectShape, plain_values};
use crate::split_doubles::SplitFloat;

/// A float type written BYTE_STREAM_SPLIT (its Parquet and Arrow types are
/// [`SplitFloat`]'s, which reads it back): its Arrow array type, its statistics, and how a
/// page's values split into byte streams.
pub(crate) trait PageFloat:
    SplitFloat + PartialOrd + bytemuck::Pod + ArrowNativeType
{
    /// Its Arrow primitive type.
    type Arrow: ArrowPrimitiveType<Native = Self>;
    /// Bytes a value (and streams a page).
    const SIZE: usize;
    /// +∞ and −∞: the bounds of no value.
    const INFINITY: Self;
    const NEG_INFINITY: Self;
    /// −0 and +0: a zero minimum and a zero maximum as the format writes them.
    const NEG_ZERO: Self;
    const ZERO: Self;
    /// The chunk statistics parquet-rs's writer makes of these bounds and no nulls.
    fn statistics(min: Option<Self>, max: Option<Self>, backwards_compatible: bool) -> Statistics;
    /// The byte streams of `values` into `out` (`SIZE × values.len()` bytes): byte `j` of
    /// value `i` at `j × values.len() + i`.
    fn split(values: &[Self], out: &mut [u8]);
}

/// [`PageFloat`] for `$t` (`$arrow` its Arrow type, `$size` its bytes).
macro_rules! page_float {
    ($t:ty, $arrow:ty, $size:literal) => {
        impl PageFloat for $t {
            type Arrow = $arrow;
            const SIZE: usize = $size;
            const INFINITY: $t = <$t>::INFINITY;
            const NEG_INFINITY: $t = <$t>::NEG_INFINITY;
            const NEG_ZERO: $t = -0.0;
            const ZERO: $t = 0.0;
            fn statistics(
                min: Option<$t>,
                max: Option<$t>,
                backwards_compatible: bool,
            ) -> Statistics {
                ValueStatistics::new(min, max, None, Some(0), false)
                    .with_backwards_compatible_min_max(backwards_compatible)
                    .into()
            }
            fn split(values: &[$t], out: &mut [u8]) {
                split_streams::<$size>(bytemuck::cast_slice(values), out);
            }
        }
    };
}

page_float!(f64, Float64Type, 8);
page_float!(f32, Float32Type, 4);

/// The byte streams of `src` (values of `N` bytes) into `out`, as long: byte `j` of value
/// `i` at `j n + i`.
fn split_streams<const N: usize>(src: &[u8], out: &mut [u8]) {
    assert_eq!(src.len(), out.len(), "as many bytes out as in");
    let n = src.len() / N;
    #[cfg(target_arch = "x86_64")]
    let done = split_sixteen_at_a_time::<N>(src, out);
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for i in done..n {
        for j in 0..N {
            out[j * n + i] = src[i * N + j];
        }
    }
}

/// [`split_streams`] of `N`-byte values (`N` a power of two up to 16) sixteen at a time
/// (SSE2, x86-64's baseline). The `16 N` bytes of values `i..i + 16` lie in `N`
/// registers: byte `b` of value `v` at the position whose bits are `v b` (4 bits of `v`,
/// log₂ `N` of `b`). Unpacking the bytes of registers `k` and `k + N/2` into registers
/// `2k` (their low halves) and `2k + 1` (high) rotates those bits left by one; four
/// rounds make them `b v`, so register `b` holds byte `b` of the sixteen values in order:
/// one store into stream `b`. Returns how many values it split (a multiple of 16).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
fn split_sixteen_at_a_time<const N: usize>(src: &[u8], out: &mut [u8]) -> usize {
    use std::arch::x86_64::{
        __m128i, _mm_loadu_si128, _mm_storeu_si128, _mm_unpackhi_epi8, _mm_unpacklo_epi8,
    };
    assert!(
        N.is_power_of_two() && (2..=16).contains(&N),
        "{N}-byte values"
    );
    assert_eq!(src.len(), out.len(), "as many bytes out as in");
    let n = src.len() / N;
    let whole = n - n % 16;
    let mut i = 0;
    while i < whole {
        // SAFETY: SSE2 is in every x86-64 CPU. The loads read bytes `N i` to
        // `N i + 16 N - 1` of `src`, within it as `i + 16 ≤ n`; the store into stream `b`
        // writes bytes `b n + i` to `b n + i + 15` of `out` (`N n` long), within it;
        // unaligned loads and stores.
        unsafe {
            let mut r: [__m128i; N] =
                std::array::from_fn(|k| _mm_loadu_si128(src.as_ptr().add(N * i + 16 * k).cast()));
            for _ in 0..4 {
                r = std::array::from_fn(|m| {
                    let (a, b) = (r[m / 2], r[m / 2 + N / 2]);
                    if m % 2 == 0 {
                        _mm_unpacklo_epi8(a, b)
                    } else {
                        _mm_unpackhi_epi8(a, b)
                    }
                });
            }
            for (b, stream) in r.iter().enumerate() {
                _mm_storeu_si128(out.as_mut_ptr().add(b * n + i).cast(), *stream);
            }
        }
        i += 16;
    }
    whole
}

/// The least and greatest of values that are not NaN, in eight lanes (any order gives the
/// same bounds: equal floats have equal bits but for zeros, whose sign the format fixes).
#[derive(Debug, Clone, Copy)]
struct Bounds<T> {
    min: [T; 8],
    max: [T; 8],
}

impl<T: PageFloat> Bounds<T> {
    fn new() -> Self {
        Self {
            min: [T::INFINITY; 8],
            max: [T::NEG_INFINITY; 8],
        }
    }

    fn push(&mut self, values: &[T]) {
        // Value `k` of every eight to lane `k`; a NaN is neither less nor greater: left out.
        let mut lanes = |eight: &[T]| {
            for ((&v, lo), hi) in eight.iter().zip(&mut self.min).zip(&mut self.max) {
                if v < *lo {
                    *lo = v;
                }
                if v > *hi {
                    *hi = v;
                }
            }
        };
        let mut eights = values.chunks_exact(8);
        eights.by_ref().for_each(&mut lanes);
        lanes(eights.remainder());
    }

    /// The bounds as parquet-rs states them: none without a value that is not NaN; a zero
    /// minimum as −0, a zero maximum as +0.
    fn get(&self) -> Option<(T, T)> {
        let mut min = self.min[0];
        let mut max = self.max[0];
        for k in 1..8 {
            if self.min[k] < min {
                min = self.min[k];
            }
            if self.max[k] > max {
                max = self.max[k];
            }
        }
        if min > max {
            return None;
        }
        // Zero of either sign equals both.
        let min = if min == T::ZERO { T::NEG_ZERO } else { min };
        let max = if max == T::ZERO { T::ZERO } else { max };
        Some((min, max))
    }
}

/// What a page is encoded with, whichever column it is of: a zstd context and that
/// context's level (made once, reset by each compression), and buffers for a page's bytes
/// before and after compression (the memory one page needs, taken once for many pages
/// rather than once a column).
#[derive(Default)]
struct PageScratch {
    zstd: Option<(i32, zstd::bulk::Compressor<'static>)>,
    uncompressed: Vec<u8>,
    compressed: Vec<u8>,
}

/// Scratches not in use, for the next pages of any column on any thread.
static SPARE_SCRATCHES: Mutex<Vec<PageScratch>> = Mutex::new(Vec::new());

/// At most how many scratches are kept between pages: as many as the machine has cores
/// (pages encoded on more threads at once take scratches of their own, let go after).
/// One a thread kept them for as long as the thread: a 12-hour run on 16 threads held
/// 30 MB of them through its disupt stage (4.4 MB each at most), written by earlier
/// stages.
fn scratches_kept() -> usize {
    static KEPT: OnceLock<usize> = OnceLock::new();
    *KEPT.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// `f` with a spare scratch, or a new one when none is spare; kept after it unless
/// [`scratches_kept`] are already.
fn with_scratch<R>(f: impl FnOnce(&mut PageScratch) -> R) -> R {
    let spare = || SPARE_SCRATCHES.lock().unwrap_or_else(|e| e.into_inner());
    let mut scratch = spare().pop().unwrap_or_default();
    let r = f(&mut scratch);
    let mut kept = spare();
    if kept.len() < scratches_kept() {
        kept.push(scratch);
    }
    r
}

/// The page whose bytes `fill` writes (into an empty buffer) at zstd `level`, as
/// parquet-rs's codec compresses a page: its compressed bytes and its size before
/// compression (see [`PageScratch::page`]).
pub(crate) fn compressed_page(
    level: i32,
    fill: impl FnOnce(&mut Vec<u8>),
) -> Result<(Bytes, usize), ParquetError> {
    with_scratch(|scratch| {
        scratch.uncompressed.clear();
        fill(&mut scratch.uncompressed);
        scratch.compress(level)
    })
}

impl PageScratch {
    /// The page of `values` (the bytes `levels` before them, if any) at zstd `level`, as
    /// parquet-rs's codec compresses a page (one frame by the bulk API): its compressed
    /// bytes and its size before compression.
    fn page<T: PageFloat>(
        &mut self,
        levels: &[u8],
        values: &[T],
        level: i32,
    ) -> Result<(Bytes, usize), ParquetError> {
        let u = &mut self.uncompressed;
        // Sized, not emptied and filled with zeros: every byte is written below, and
        // only a longer page than the scratch has held zeroes the bytes it adds (the
        // zeros were 13 MB a 40-minute ingest, 2 % of its instructions).
        u.resize(levels.len() + values.len() * T::SIZE, 0);
        u[..levels.len()].copy_from_slice(levels);
        T::split(values, &mut u[levels.len()..]);
        self.compress(level)
    }

    /// The uncompressed buffer's bytes at zstd `level`, as parquet-rs's codec compresses a
    /// page (one frame by the bulk API): its compressed bytes and its size before
    /// compression.
    fn compress(&mut self, level: i32) -> Result<(Bytes, usize), ParquetError> {
        let u = &mut self.uncompressed;
        let c = &mut self.compressed;
        c.clear();
        c.reserve(zstd::zstd_safe::compress_bound(u.len()));
        let compressor = match &mut self.zstd {
            Some((l, compressor)) if *l == level => compressor,
            slot => {
                let made = zstd::bulk::Compressor::new(level)
                    .map_err(|e| ParquetError::External(Box::new(e)))?;
                &mut slot.insert((level, made)).1
            }
        };
        compressor
            .compress_to_buffer(u.as_slice(), c)
            .map_err(|e| ParquetError::External(Box::new(e)))?;
        Ok((Bytes::copy_from_slice(c), u.len()))
    }
}

/// A float column without nulls, flat or in lists of a fixed length, written as
/// BYTE_STREAM_SPLIT pages (see the module's notes).
pub(crate) struct SplitColumn<T> {
    descr: ColumnDescPtr,
    shape: DirectShape,
    /// A list's levels, encoded for a page of the last count of values asked.
    levels: Option<ListLevels>,
    settings: PageSettings,
    /// Values of the page being filled that came in an earlier batch (between batches:
    /// all of that page's).
    kept: Vec<T>,
    bounds: Bounds<T>,
    /// The chunk's pages so far.
    chunk: ChunkLedger,
}

impl<T: PageFloat> SplitColumn<T> {
    /// A writer of the leaf `descr` with the file's `props`, or `None` unless the column is
    /// one of `T` laid out as `shape` says (flat, or a list's leaf repeated once) and its
    /// settings are the tables': version 1 pages, no dictionary, BYTE_STREAM_SPLIT, chunk
    /// statistics, no bloom filter, zstd.
    pub(crate) fn new(
        descr: ColumnDescPtr,
        props: WriterPropertiesPtr,
        shape: DirectShape,
    ) -> Option<Self> {
        let levels = match shape {
            DirectShape::Flat if descr.max_def_level() == 0 && descr.max_rep_level() == 0 => None,
            DirectShape::List { len } if len > 0 && descr.max_rep_level() == 1 => {
                Some(ListLevels::new(len, descr.max_def_level())?)
            }
            _ => return None,
        };
        let settings = PageSettings::of(
            &descr,
            &props,
            <T as SplitFloat>::PHYSICAL,
            Encoding::BYTE_STREAM_SPLIT,
        )?;
        Some(Self {
            chunk: ChunkLedger::new(
                descr.clone(),
                &props,
                Encoding::BYTE_STREAM_SPLIT,
                settings.zstd,
            ),
            descr,
            shape,
            levels,
            settings,
            kept: Vec::new(),
            bounds: Bounds::new(),
        })
    }

    /// Values a row: 1, or the lists' length.
    fn per_row(&self) -> usize {
        match self.shape {
            DirectShape::Flat | DirectShape::Nullable => 1,
            DirectShape::List { len } => len,
        }
    }

    /// Encodes the rows of `column` (laid out as the column's shape says, without nulls).
    pub(crate) fn write_array(&mut self, column: &ArrayRef) -> Result<(), ParquetError> {
        let values = plain_values(column, self.shape)?;
        let values = values.as_primitive_opt::<T::Arrow>().ok_or_else(|| {
            ParquetError::General(format!(
                "{} values for {}",
                values.data_type(),
                <T as SplitFloat>::ARROW
            ))
        })?;
        self.write(values.values().as_ref())
    }

    /// Encodes `values`, `per_row` a row: batches of `write_batch_size` values from its
    /// first, each to the end of its last row, a page cut after the batch that fills it.
    fn write(&mut self, values: &[T]) -> Result<(), ParquetError> {
        let per_row = self.per_row();
        if !values.len().is_multiple_of(per_row) {
            return Err(ParquetError::General(format!(
                "{} values in rows of {per_row}",
                values.len()
            )));
        }
        self.bounds.push(values);
        // Values of `values` from `start` on are in the page being filled, after the
        // kept ones.
        let mut start = 0;
        let mut end = 0;
        while end < values.len() {
            end = (end + self.settings.batch)
                .min(values.len())
                .next_multiple_of(per_row);
            let page_len = self.kept.len() + end - start;
            let full = page_len / per_row >= self.settings.page_rows
                || page_len * T::SIZE >= self.settings.page_bytes;
            if full {
                if self.kept.is_empty() {
                    self.page(&values[start..end])?;
                } else {
                    let mut kept = std::mem::take(&mut self.kept);
                    kept.extend_from_slice(&values[start..end]);
                    self.page(&kept)?;
                    kept.clear();
                    self.kept = kept;
                }
                start = end;
            }
        }
        self.kept.extend_from_slice(&values[start..]);
        Ok(())
    }

    /// Writes the page of `values` (whole rows).
    fn page(&mut self, values: &[T]) -> Result<(), ParquetError> {
        let n = values.len();
        let rows = n / self.per_row();
        // Version 1 pages: the repetition levels, the definition levels, the values.
        let levels = self.levels.as_mut().map_or(&[][..], |l| l.encoded(n));
        let level = self.chunk.zstd().compression_level();
        let (buf, uncompressed) = with_scratch(|scratch| scratch.page(levels, values, level))?;
        self.chunk.push(buf, uncompressed, rows, n, 0)
    }

    /// Writes the last page and returns the chunk's pages and what the row group records
    /// of them.
    pub(crate) fn close(mut self) -> Result<(ChunkPages, ColumnCloseResult), ParquetError> {
        if !self.kept.is_empty() {
            let kept = std::mem::take(&mut self.kept);
            self.page(&kept)?;
        }
        let bounds = self.bounds.get();
        let backwards_compatible = self.descr.sort_order().is_signed();
        self.chunk.close(T::statistics(
            bounds.map(|b| b.0),
            bounds.map(|b| b.1),
            backwards_compatible,
        ))
    }
}

/// The levels of a page of a fixed-size list column whose lists and values are required:
/// each value defined (at the column's maximum level), each row's first value at
/// repetition level 0 and the others at 1. A page always begins a row, so its levels
/// depend on its count of values only: the last count's are kept encoded.
struct ListLevels {
    per_row: usize,
    max_def: u8,
    /// Pages' counts of values and their levels encoded (repetition, then definition),
    /// the last asked first, up to [`LEVELS_KEPT`].
    encoded: Vec<(usize, Vec<u8>)>,
}

/// How many pages' levels a list column keeps encoded: its pages take a few lengths in
/// turn (cut after the write batch that fills them, batches counted from each array's
/// start: a 4-hour IMU table's two list columns, in two row groups, asked for 90
/// encodings of about 60 000 values when only the last was kept, 30 with four).
const LEVELS_KEPT: usize = 4;

impl ListLevels {
    /// `None` for a definition level past a byte (not a column the tables write).
    fn new(per_row: usize, max_def: i16) -> Option<Self> {
        Some(Self {
            per_row,
            max_def: u8::try_from(max_def).ok()?,
            encoded: Vec::with_capacity(LEVELS_KEPT),
        })
    }

    /// The levels of a page of `n` values, as version 1 pages hold them.
    fn encoded(&mut self, n: usize) -> &[u8] {
        match self.encoded.iter().position(|(m, _)| *m == n) {
            Some(i) => self.encoded[..=i].rotate_right(1),
            None => {
                let mut bytes = rle_repetition(n, self.per_row);
                bytes.extend(rle_constant(n, self.max_def));
                self.encoded.truncate(LEVELS_KEPT - 1);
                self.encoded.insert(0, (n, bytes));
            }
        }
        &self.encoded[0].1
    }
}

/// `levels` (each below 2^`width`, `width` ≤ 8) in Parquet's RLE / bit-packed hybrid
/// encoding behind their length in 4 bytes, as a version 1 page holds them: the bytes
/// parquet-rs's `RleEncoder` writes (a port of its choices: values taken eight at a
/// time, a run of eight equal ones or more encoded as a run, up to 63 groups of eight a
/// bit-packed run, the last group padded with zeros).
pub(crate) fn rle_hybrid(levels: &[u8], width: u8) -> Vec<u8> {
    let mut e = Rle {
        out: vec![0; 4],
        width,
        buffered: [0; 8],
        n_buffered: 0,
        current: 0,
        repeat: 0,
        bit_packed: 0,
        indicator: None,
    };
    for &v in levels {
        e.put(v);
    }
    e.flush();
    let len = u32::try_from(e.out.len() - 4).unwrap_or(u32::MAX);
    e.out[..4].copy_from_slice(&len.to_le_bytes());
    e.out
}

/// `v` as ULEB128, as Parquet's encodings write their headers (parquet-rs's
/// `put_vlq_int`).
pub(crate) fn put_uleb128(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7F) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// [`rle_hybrid`] of `n` values all `level`, without going through them: one RLE run of
/// them (of none, nothing), as its port of parquet-rs's `RleEncoder` writes it. Their
/// first eight (or all, when fewer) are buffered as equal, then the rest counted
/// without being buffered; the end flushes the run.
pub(crate) fn rle_constant(n: usize, level: u8) -> Vec<u8> {
    let mut out = vec![0; 4];
    if n > 0 {
        put_uleb128(&mut out, (n << 1) as u64);
        out.push(level);
    }
    let len = u32::try_from(out.len() - 4).unwrap_or(u32::MAX);
    out[..4].copy_from_slice(&len.to_le_bytes());
    out
}

/// [`rle_hybrid`] of the repetition levels of `n` values in rows of `per_row` (each row's
/// first value 0, the others 1), at a width of 1: for rows of 2 to 8 values, without going
/// through the values. No eight of those levels in a row are equal, so the port writes
/// each whole group of eight bit-packed (one byte), in runs of at most 63 groups; the
/// last values, fewer than eight, go padded into the last run when one is open, else as
/// a run of their own: RLE when they are all equal, else one bit-packed group. The
/// groups' bytes repeat with the rows.
fn rle_repetition(n: usize, per_row: usize) -> Vec<u8> {
    let level = |k: usize| u8::from(!k.is_multiple_of(per_row.max(1)));
    if per_row <= 1 {
        return rle_constant(n, 0);
    }
    if per_row > 8 {
        let levels: Vec<u8> = (0..n).map(level).collect();
        return rle_hybrid(&levels, 1);
    }
    // Group `g`'s byte is the `g % per_row`th (8 g mod per_row repeats with that period).
    let group_byte = |g: usize| (0..8).fold(0u8, |b, j| b | (level(8 * g + j) << j));
    let bytes: Vec<u8> = (0..per_row).map(group_byte).collect();
    let groups = n / 8;
    let rest = n % 8;
    let mut out = vec![0; 4];
    out.reserve(groups + groups / 63 + 4);
    let mut g = 0;
    let run = |out: &mut Vec<u8>, from: usize, len: usize, extra: usize| {
        out.push((((len + extra) << 1) | 1) as u8);
        out.extend((from..from + len).map(|g| bytes[g % per_row]));
    };
    while groups - g >= 63 {
        run(&mut out, g, 63, 0);
        g += 63;
    }
    let open = groups - g;
    // The last values' group, padded with zeros.
    let last = (0..rest).fold(0u8, |b, j| b | (level(8 * groups + j) << j));
    if rest == 0 {
        if open > 0 {
            run(&mut out, g, open, 0);
        }
    } else if open > 0 {
        run(&mut out, g, open, 1);
        out.push(last);
    } else if (1..rest).all(|j| level(8 * groups + j) == level(8 * groups)) {
        out.push((rest << 1) as u8);
        out.push(level(8 * groups));
    } else {
        out.push(3);
        out.push(last);
    }
    let len = u32::try_from(out.len() - 4).unwrap_or(u32::MAX);
    out[..4].copy_from_slice(&len.to_le_bytes());
    out
}

/// The state of [`rle_hybrid`]: parquet-rs's `RleEncoder`'s, field for field.
struct Rle {
    out: Vec<u8>,
    width: u8,
    buffered: [u8; 8],
    n_buffered: usize,
    current: u8,
    repeat: usize,
    /// Values in the bit-packed run being written.
    bit_packed: usize,
    /// Where that run's header byte goes.
    indicator: Option<usize>,
}

impl Rle {
    fn put(&mut self, v: u8) {
        if self.current == v {
            self.repeat += 1;
            if self.repeat > 8 {
                return;
            }
        } else {
            if self.repeat >= 8 {
                self.flush_rle_run();
            }
            self.repeat = 1;
            self.current = v;
        }
        self.buffered[self.n_buffered] = v;
        self.n_buffered += 1;
        if self.n_buffered == 8 {
            self.flush_buffered();
        }
    }

    fn flush(&mut self) {
        if self.bit_packed > 0 || self.repeat > 0 || self.n_buffered > 0 {
            let all_repeat =
                self.bit_packed == 0 && (self.repeat == self.n_buffered || self.n_buffered == 0);
            if self.repeat > 0 && all_repeat {
                self.flush_rle_run();
            } else {
                if self.n_buffered > 0 {
                    self.buffered[self.n_buffered..].fill(0);
                    self.n_buffered = 8;
                }
                self.bit_packed += self.n_buffered;
                self.flush_bit_packed_run(true);
                self.repeat = 0;
            }
        }
    }

    fn flush_rle_run(&mut self) {
        put_uleb128(&mut self.out, (self.repeat << 1) as u64);
        // The value in whole bytes: one, as `width` ≤ 8.
        self.out.push(self.current);
        self.n_buffered = 0;
        self.repeat = 0;
    }

    fn flush_bit_packed_run(&mut self, end_run: bool) {
        if self.indicator.is_none() {
            self.indicator = Some(self.out.len());
            self.out.push(0);
        }
        // Eight values of `width` bits, the first in the lowest: `width` bytes.
        if self.n_buffered > 0 {
            let packed = self.buffered[..self.n_buffered]
                .iter()
                .enumerate()
                .fold(0u64, |acc, (k, &v)| {
                    acc | (u64::from(v) << (k * self.width as usize))
                });
            let bytes = packed.to_le_bytes();
            self.out.extend_from_slice(&bytes[..self.width as usize]);
        }
        self.n_buffered = 0;
        if end_run {
            self.finish_bit_packed_run();
        }
    }

    fn finish_bit_packed_run(&mut self) {
        let groups = self.bit_packed / 8;
        if let Some(at) = self.indicator.take() {
            self.out[at] = ((groups << 1) | 1) as u8;
        }
        self.bit_packed = 0;
    }

    fn flush_buffered(&mut self) {
        if self.repeat >= 8 {
            self.n_buffered = 0;
            if self.bit_packed > 0 {
                self.finish_bit_packed_run();
            }
            return;
        }
        self.bit_packed += self.n_buffered;
        let groups = self.bit_packed / 8;
        self.flush_bit_packed_run(groups + 1 >= 64);
        self.repeat = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The byte streams of values of `N` bytes, one byte at a time.
    fn split_naively<const N: usize>(src: &[u8]) -> Vec<u8> {
        let n = src.len() / N;
        let mut out = vec![0; src.len()];
        for i in 0..n {
            for j in 0..N {
                out[j * n + i] = src[i * N + j];
            }
        }
        out
    }

    /// Sixteen at a time (and the rest one by one) gives the streams byte for byte, for
    /// every count around the blocks' edges and beyond.
    #[test]
    fn list_levels_kept_for_a_few_page_lengths_are_those_encoded_afresh() {
        let fresh = |n: usize| ListLevels::new(3, 2).unwrap().encoded(n).to_vec();
        let mut kept = ListLevels::new(3, 2).unwrap();
        // Lengths in turn, more of them than are kept, some asked again at once.
        for n in [
            60_534, 60_150, 60_534, 60_150, 60_174, 60_174, 3, 9, 60_534, 0, 3, 60_150,
        ] {
            assert_eq!(kept.encoded(n), fresh(n), "{n} values");
            assert!(kept.encoded.len() <= LEVELS_KEPT);
            assert_eq!(kept.encoded[0].0, n, "the last asked first");
        }
        let repeated: Vec<usize> = kept.encoded.iter().map(|(n, _)| *n).collect();
        assert_eq!(repeated, [60_150, 3, 0, 60_534]);
    }

    /// Bits of the widest level up to `max_level`.
    fn bits_for(max_level: u8) -> u8 {
        (u8::BITS - max_level.leading_zeros()) as u8
    }

    /// Constant levels' encoding, as the port of parquet-rs's encoder writes them, for
    /// every count around its groups of eight and its headers' bytes, every width.
    #[test]
    fn constant_levels_are_one_run_as_the_encoder_writes_them() {
        let counts = (0..=1100).chain([8191, 8192, 16_383, 16_384, 60_000, 2_097_151, 2_097_152]);
        for n in counts {
            for level in [0u8, 1, 2, 3, 7, 200, 255] {
                let width = bits_for(level).max(1);
                assert_eq!(
                    rle_constant(n, level),
                    rle_hybrid(&vec![level; n], width),
                    "{n} values of {level}"
                );
            }
        }
    }

    /// Repetition levels of rows of every length, as the port of parquet-rs's encoder
    /// writes them, for every count around its groups of eight and its runs of 63.
    #[test]
    fn repetition_levels_are_encoded_as_the_encoder_writes_them() {
        for per_row in 1..=12usize {
            for n in (0..=2100).chain([8 * 63 * 40, 8 * 63 * 40 + 3, 60_000, 60_003]) {
                let levels: Vec<u8> = (0..n).map(|k| u8::from(k % per_row != 0)).collect();
                assert_eq!(
                    rle_repetition(n, per_row),
                    rle_hybrid(&levels, 1),
                    "{n} values in rows of {per_row}"
                );
            }
        }
    }

    /// Repetition levels of lists of every length to past a group of eight, encoded as
    /// their plain definition says.
    #[test]
    fn list_levels_are_those_of_their_rows() {
        for per_row in 1..=12usize {
            for rows in [0usize, 1, 2, 3, 7, 8, 9, 168, 169, 20_000] {
                let n = rows * per_row;
                let repetition: Vec<u8> = (0..n).map(|k| u8::from(k % per_row != 0)).collect();
                let mut expected = rle_hybrid(&repetition, 1);
                expected.extend(rle_hybrid(&vec![2; n], bits_for(2)));
                let mut levels = ListLevels::new(per_row, 2).unwrap();
                assert_eq!(levels.encoded(n), expected, "{rows} rows of {per_row}");
            }
        }
    }

    /// Pages encoded on more threads at once than the machine has cores each take a
    /// scratch; no more are kept after them than it has cores, and the pages are the
    /// same as with scratches alone.
    #[test]
    fn scratches_kept_are_no_more_than_the_cores() {
        let values: Vec<f64> = (0..100_000).map(|k| (k as f64).sqrt()).collect();
        let alone = PageScratch::default().page(&[], &values, 3).unwrap();
        let threads = scratches_kept() + 6;
        let all_in = std::sync::Barrier::new(threads);
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| {
                    with_scratch(|scratch| {
                        all_in.wait();
                        assert_eq!(scratch.page(&[], &values, 3).unwrap(), alone);
                    })
                });
            }
        });
        let kept = SPARE_SCRATCHES.lock().unwrap().len();
        assert!(kept <= scratches_kept(), "{kept} kept");
    }

    #[test]
    fn streams_are_split_as_byte_by_byte() {
        for n in (0..70).chain([1000, 20_480, 20_483]) {
            let doubles: Vec<f64> = (0..n).map(|k| (k as f64 * 0.7).sin() * 1e5).collect();
            let mut out = vec![0xAA; 8 * n];
            f64::split(&doubles, &mut out);
            assert_eq!(
                out,
                split_naively::<8>(bytemuck::cast_slice(&doubles)),
                "{n} f64"
            );
            let floats: Vec<f32> = doubles.iter().map(|&x| x as f32).collect();
            let mut out = vec![0xAA; 4 * n];
            f32::split(&floats, &mut out);
            assert_eq!(
                out,
                split_naively::<4>(bytemuck::cast_slice(&floats)),
                "{n} f32"
            );
        }
    }

    /// The bounds leave NaNs out, state zeros as the format does, and are none without
    /// a number; infinities count.
    #[test]
    fn bounds_leave_nans_out_and_fix_zeros_signs() {
        let bounds = |v: &[f64]| {
            let mut b = Bounds::new();
            b.push(v);
            b.get().map(|(lo, hi)| (lo.to_bits(), hi.to_bits()))
        };
        let bits = |lo: f64, hi: f64| Some((lo.to_bits(), hi.to_bits()));
        assert_eq!(bounds(&[]), None);
        assert_eq!(bounds(&[f64::NAN; 11]), None);
        assert_eq!(bounds(&[f64::NAN, 2.0, -3.0, f64::NAN]), bits(-3.0, 2.0));
        assert_eq!(bounds(&[0.0, 5.0]), bits(-0.0, 5.0));
        assert_eq!(bounds(&[-0.0, -5.0, 0.0]), bits(-5.0, 0.0));
        assert_eq!(
            bounds(&[f64::INFINITY; 3]),
            bits(f64::INFINITY, f64::INFINITY)
        );
        let many: Vec<f64> = (0..1001)
            .map(|k| ((k * 37) % 1001) as f64 - 500.0)
            .collect();
        assert_eq!(bounds(&many), bits(-500.0, 500.0));
    }
}
