//! A fast read of the tables' float columns stored as Parquet's BYTE_STREAM_SPLIT.
//!
//! Every float column the tables write is BYTE_STREAM_SPLIT (each value's bytes in as
//! many streams: byte 0 of every value, then byte 1, …), which compresses well; the
//! parquet crate joins the streams back one byte at a time, a quarter of what reading a
//! run's angle increments costs. Here a column's pages are read as they are stored
//! (decompressed by the crate's page reader) and their streams joined sixteen values at
//! a time by SSE2's byte unpacking (x86-64's baseline), into the caller's values.
//!
//! Only the layout the tables write is taken: an f64 or f32 column with no nulls, or a
//! list of f64 with a fixed number per row and no nulls (levels skipped, their count checked
//! against the values'), every page BYTE_STREAM_SPLIT. Any other file gives `None`, and
//! the caller reads it through Arrow: the same values either way.

use std::path::Path;

use parquet::basic::{Encoding, Type as PhysicalType};
use parquet::column::page::Page;
use parquet::file::reader::{FileReader, SerializedFileReader};

use crate::error::{FileError, FormatError, io_in_file};
use crate::parquet_io::ROWS_PER_FILE_BYTE_MAX;

/// A float type the tables store BYTE_STREAM_SPLIT: its Parquet and Arrow types, and how
/// a page's byte streams join back into values.
pub trait SplitFloat: Copy + Default {
    /// Its Parquet physical type.
    const PHYSICAL: PhysicalType;
    /// Its Arrow type.
    const ARROW: arrow::datatypes::DataType;
    /// The values of one page's byte streams `src` (`size_of::<Self>() × out.len()`
    /// bytes), into `out`.
    fn join(src: &[u8], out: &mut [Self]);
}

impl SplitFloat for f64 {
    const PHYSICAL: PhysicalType = PhysicalType::DOUBLE;
    const ARROW: arrow::datatypes::DataType = arrow::datatypes::DataType::Float64;
    fn join(src: &[u8], out: &mut [f64]) {
        join_streams(src, out);
    }
}

impl SplitFloat for f32 {
    const PHYSICAL: PhysicalType = PhysicalType::FLOAT;
    const ARROW: arrow::datatypes::DataType = arrow::datatypes::DataType::Float32;
    fn join(src: &[u8], out: &mut [f32]) {
        join_streams_f32(src, out);
    }
}

/// The values of the leaf column `leaf` (its dotted path, e.g. `x` or `v.list.item`) of
/// the Parquet file `path`, when it holds `per_row` doubles in every row with no nulls,
/// stored BYTE_STREAM_SPLIT in every page: all of them, in order (`per_row` a row).
/// `Ok(None)` for any other layout (a dictionary, another encoding or type, nulls, rows
/// of other lengths, no such column), which the caller reads through Arrow.
///
/// # Errors
/// If the file cannot be read or is not Parquet.
pub fn read_split_doubles(
    path: &Path,
    leaf: &str,
    per_row: usize,
) -> Result<Option<Vec<f64>>, FileError> {
    let Some(pages) = Pages::open::<f64>(path, leaf, per_row)? else {
        return Ok(None);
    };
    // Room for the values the metadata counts, within a bound of the file's length (its
    // counts are the file's word, not a bound); each page joined where it lands.
    let mut values: Vec<f64> = Vec::with_capacity(pages.room_for_rows(per_row));
    let whole = pages.walk::<f64>(path, |streams, at| {
        reserve_up_to(&mut values, at + streams.len() / 8, pages.total);
        values.resize(at + streams.len() / 8, 0.0);
        f64::join(streams, &mut values[at..]);
    })?;
    Ok(whole.then_some(values))
}

/// [`read_split_doubles`] of a list column `name` of three doubles a row, a row each.
pub fn read_split_vec3(path: &Path, name: &str) -> Result<Option<Vec<[f64; 3]>>, FileError> {
    read_rows::<3>(path, &format!("{name}.list.item"))
}

/// The values of the column `name` (of `F` a row, no nulls, BYTE_STREAM_SPLIT: the
/// layout [`read_split_doubles`] takes) page by page: `each(first, values)` with each
/// page's values, `first` the index of its first. `Ok(false)` for any other layout, which
/// may have been found after some pages were handed over: the caller then drops what it
/// took and reads the column through Arrow.
///
/// # Errors
/// If the file cannot be read or is not Parquet.
pub fn for_each_split_page<F: SplitFloat>(
    path: &Path,
    name: &str,
    each: impl FnMut(usize, &[F]),
) -> Result<bool, FileError> {
    for_each_split_values(path, name, 1, each)
}

/// [`for_each_split_page`] of the leaf column `leaf` of `per_row` values a row (a list
/// column's `name.list.item`, of lists of `per_row`; the column itself for one): `first`
/// counts values, the rows' `per_row` values one after the other.
///
/// # Errors
/// If the file cannot be read or is not Parquet.
pub fn for_each_split_values<F: SplitFloat>(
    path: &Path,
    leaf: &str,
    per_row: usize,
    mut each: impl FnMut(usize, &[F]),
) -> Result<bool, FileError> {
    match Pages::open::<F>(path, leaf, per_row)? {
        Some(pages) => pages.values(path, &mut each),
        None => Ok(false),
    }
}

/// The rows of `N` doubles of the leaf column `leaf` ([`read_split_doubles`]), grown as
/// the pages are read: no more is allocated up front than [`Pages::room_for_rows`] says
/// (its metadata's counts are the file's word, not a bound), and each page's values are
/// joined into a buffer of the page's size, then taken row by row ([`Rows`]).
fn read_rows<const N: usize>(path: &Path, leaf: &str) -> Result<Option<Vec<[f64; N]>>, FileError> {
    let Some(pages) = Pages::open::<f64>(path, leaf, N)? else {
        return Ok(None);
    };
    let claimed = pages.total / N;
    let mut rows = Rows::<N>::with_capacity(pages.room_for_rows(N) / N);
    let whole = pages.values::<f64>(path, |_, values| {
        let len = rows.rows.len() + (rows.held + values.len()) / N;
        reserve_up_to(&mut rows.rows, len, claimed);
        rows.take(values)
    })?;
    Ok(rows.finish().filter(|_| whole))
}

/// Makes room in `v` for `len` items in all, growing it as a vector grows (twice what it
/// had) but to no more than `claimed`, the metadata's count, unless `len` is beyond it: an
/// honest file's values fill it exactly (a compressed file holds more values than bytes,
/// and grown by doubling past its count a 12-hour odometer column took 59 MB for 35 MB);
/// an untrusted count still allocates no more than twice the values read.
fn reserve_up_to<T>(v: &mut Vec<T>, len: usize, claimed: usize) {
    if len > v.capacity() {
        let room = v
            .capacity()
            .saturating_mul(2)
            .max(len)
            .min(claimed.max(len));
        v.reserve_exact(room - v.len());
    }
}

/// Rows of `N` values from series of values that may end mid-row (a page's).
struct Rows<const N: usize> {
    rows: Vec<[f64; N]>,
    /// The row the values so far left open, and how much of it they gave.
    open: [f64; N],
    held: usize,
}

impl<const N: usize> Rows<N> {
    fn with_capacity(rows: usize) -> Self {
        Self {
            rows: Vec::with_capacity(rows),
            open: [0.0; N],
            held: 0,
        }
    }

    /// The next values, in order.
    fn take(&mut self, mut values: &[f64]) {
        // The open row first, then the whole rows, then the new open one.
        if self.held > 0 {
            let n = (N - self.held).min(values.len());
            self.open[self.held..self.held + n].copy_from_slice(&values[..n]);
            self.held += n;
            values = &values[n..];
            if self.held < N {
                return;
            }
            self.rows.push(self.open);
            self.held = 0;
        }
        let whole = values.chunks_exact(N);
        let rest = whole.remainder();
        self.rows
            .extend(whole.map(|r| std::array::from_fn(|i| r[i])));
        self.open[..rest.len()].copy_from_slice(rest);
        self.held = rest.len();
    }

    /// The rows, unless one is left open.
    fn finish(self) -> Option<Vec<[f64; N]>> {
        (self.held == 0).then_some(self.rows)
    }
}

/// A column of the tables' layout, its pages to read.
struct Pages {
    reader: SerializedFileReader<std::fs::File>,
    column: usize,
    /// Its values, as the metadata says.
    total: usize,
    /// The file's length, bytes: what is allocated before the values are read is
    /// bounded by a multiple of it ([`Pages::room_for_rows`]).
    file_bytes: usize,
    /// Level runs before a version-1 page's values (repetition, definition).
    level_runs: usize,
}

impl Pages {
    /// The leaf column `leaf` of `path`, when it holds `per_row` values of `F` in every
    /// row with no nulls ([`read_split_doubles`]); `None` for another layout.
    fn open<F: SplitFloat>(
        path: &Path,
        leaf: &str,
        per_row: usize,
    ) -> Result<Option<Self>, FileError> {
        let err = |e: parquet::errors::ParquetError| FormatError::from(e).in_file(path);
        let file = std::fs::File::open(path).map_err(|e| io_in_file(path, e))?;
        let file_bytes = file
            .metadata()
            .map_err(|e| io_in_file(path, e))
            .map(|m| usize::try_from(m.len()).unwrap_or(usize::MAX))?;
        let reader = SerializedFileReader::new(file).map_err(err)?;
        let meta = reader.metadata();
        let schema = meta.file_metadata().schema_descr();
        // The Arrow type the file was written with: the float, or a list of `per_row` of
        // them, with no nulls (the list's rows are then of that length, which its levels
        // are not read again to check).
        let Ok(arrow) = parquet::arrow::parquet_to_arrow_schema(
            schema,
            meta.file_metadata().key_value_metadata(),
        ) else {
            return Ok(None);
        };
        let top = leaf.split('.').next().unwrap_or(leaf);
        let typed = arrow.field_with_name(top).ok().is_some_and(|f| {
            !f.is_nullable()
                && match f.data_type() {
                    arrow::datatypes::DataType::FixedSizeList(item, n) => {
                        usize::try_from(*n).ok() == Some(per_row)
                            && !item.is_nullable()
                            && *item.data_type() == F::ARROW
                    }
                    t => *t == F::ARROW && per_row == 1 && top == leaf,
                }
        });
        if !typed {
            return Ok(None);
        }
        let Some(column) =
            (0..schema.num_columns()).find(|&i| schema.column(i).path().string() == leaf)
        else {
            return Ok(None);
        };
        let descr = schema.column(column);
        // No nulls: at most one repeated level (a list) whose entries are all defined.
        if descr.physical_type() != F::PHYSICAL
            || descr.max_rep_level() > 1
            || (descr.max_rep_level() == 0) != (per_row == 1)
            || per_row == 0
        {
            return Ok(None);
        }
        let rows: i64 = meta.row_groups().iter().map(|g| g.num_rows()).sum();
        let Some(total) = usize::try_from(rows)
            .ok()
            .and_then(|r| r.checked_mul(per_row))
        else {
            return Ok(None);
        };
        // The values the metadata announces: no more is allocated.
        let stored: i64 = meta
            .row_groups()
            .iter()
            .map(|g| g.column(column).num_values())
            .sum();
        if usize::try_from(stored).ok() != Some(total) {
            return Ok(None);
        }
        let level_runs =
            usize::from(descr.max_rep_level() > 0) + usize::from(descr.max_def_level() > 0);
        Ok(Some(Self {
            reader,
            column,
            total,
            file_bytes,
            level_runs,
        }))
    }

    /// How many values to make room for before reading the column's pages, `per_row` a
    /// row: the metadata's count, but for no more rows than
    /// [`ROWS_PER_FILE_BYTE_MAX`] for each byte of the file
    /// ([`row_capacity_hint`](crate::parquet_io::row_capacity_hint)'s
    /// bound), so that metadata that lies reserves a bounded multiple of the file's size.
    /// A column sized once is the vector it ends as: one grown page by page left holes of
    /// its earlier sizes in the heap (the 12-hour odometer's distances, from the file's
    /// length in values, 1.85 M, to 4.32 M).
    fn room_for_rows(&self, per_row: usize) -> usize {
        let rows = self
            .file_bytes
            .saturating_mul(ROWS_PER_FILE_BYTE_MAX as usize);
        self.total.min(rows.saturating_mul(per_row))
    }

    /// `each(first, values)` with each page's values joined into a buffer of the page's
    /// size ([`Self::walk`]).
    fn values<F: SplitFloat>(
        &self,
        path: &Path,
        mut each: impl FnMut(usize, &[F]),
    ) -> Result<bool, FileError> {
        let mut scratch: Vec<F> = Vec::new();
        self.walk::<F>(path, |streams, first| {
            scratch.resize(streams.len() / std::mem::size_of::<F>(), F::default());
            F::join(streams, &mut scratch);
            each(first, &scratch);
        })
    }

    /// `page(streams, first)` with each page's byte streams of `F` values (their first
    /// index `first`), in order; `false` when a page is not of the layout or the values
    /// are not all there.
    fn walk<F: SplitFloat>(
        &self,
        path: &Path,
        mut page: impl FnMut(&[u8], usize),
    ) -> Result<bool, FileError> {
        let err = |e: parquet::errors::ParquetError| FormatError::from(e).in_file(path);
        let size = std::mem::size_of::<F>();
        let mut at = 0;
        for g in 0..self.reader.metadata().num_row_groups() {
            let group = self.reader.get_row_group(g).map_err(err)?;
            let pages = group.get_column_page_reader(self.column).map_err(err)?;
            for p in pages {
                let (values, num_values, encoding) = match p.map_err(err)? {
                    Page::DataPage {
                        buf,
                        num_values,
                        encoding,
                        ..
                    } => {
                        // Version 1: each level's run, after its four-byte length, then
                        // the values.
                        let mut rest: &[u8] = &buf;
                        for _ in 0..self.level_runs {
                            let Some((len, after)) = rest.split_first_chunk::<4>() else {
                                return Ok(false);
                            };
                            let Some(after) = usize::try_from(u32::from_le_bytes(*len))
                                .ok()
                                .and_then(|n| after.get(n..))
                            else {
                                return Ok(false);
                            };
                            rest = after;
                        }
                        (buf.slice_ref(rest), num_values, encoding)
                    }
                    Page::DataPageV2 {
                        buf,
                        num_values,
                        encoding,
                        num_nulls,
                        def_levels_byte_len,
                        rep_levels_byte_len,
                        ..
                    } => {
                        let skip = def_levels_byte_len as usize + rep_levels_byte_len as usize;
                        if num_nulls != 0 || skip > buf.len() {
                            return Ok(false);
                        }
                        (buf.slice(skip..), num_values, encoding)
                    }
                    _ => return Ok(false),
                };
                let n = num_values as usize;
                // Every level a value (a null or an empty list has none: fewer bytes).
                if encoding != Encoding::BYTE_STREAM_SPLIT
                    || values.len() != n * size
                    || at + n > self.total
                {
                    return Ok(false);
                }
                page(&values, at);
                at += n;
            }
        }
        Ok(at == self.total)
    }
}

/// The doubles of one page's eight byte streams `src` (`8 × out.len()` bytes), into `out`.
fn join_streams(src: &[u8], out: &mut [f64]) {
    let n = out.len();
    assert_eq!(src.len(), 8 * n, "eight streams of the values' length");
    #[cfg(target_arch = "x86_64")]
    let done = join_sixteen_at_a_time(src, out);
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for (i, v) in out.iter_mut().enumerate().skip(done) {
        *v = f64::from_le_bytes(std::array::from_fn(|j| src[j * n + i]));
    }
}

/// [`join_streams`] sixteen values at a time (SSE2, x86-64's baseline): byte `j` of
/// values `i..i + 16` is one load from stream `j`, and three rounds of unpacking (bytes,
/// then pairs, then fours) give the values in order. Returns how many it joined (a
/// multiple of 16).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
fn join_sixteen_at_a_time(src: &[u8], out: &mut [f64]) -> usize {
    use std::arch::x86_64::{
        __m128i, _mm_loadu_si128, _mm_storeu_si128, _mm_unpackhi_epi8, _mm_unpackhi_epi16,
        _mm_unpackhi_epi32, _mm_unpacklo_epi8, _mm_unpacklo_epi16, _mm_unpacklo_epi32,
    };
    let n = out.len();
    assert_eq!(src.len(), 8 * n, "eight streams of the values' length");
    let whole = n - n % 16;
    let mut i = 0;
    while i < whole {
        // SAFETY: SSE2 is in every x86-64 CPU. Each load reads bytes `j n + i` to
        // `j n + i + 15` of `src` (8 n long), within it as `i + 16 ≤ n`; each store writes
        // two of `out`'s values `i..i + 16`, within it; unaligned loads and stores.
        unsafe {
            let r: [__m128i; 8] =
                std::array::from_fn(|j| _mm_loadu_si128(src.as_ptr().add(j * n + i).cast()));
            // Bytes 0 and 1, 2 and 3, … of values 0–7 (lo) and 8–15 (hi).
            let a0 = _mm_unpacklo_epi8(r[0], r[1]);
            let a1 = _mm_unpackhi_epi8(r[0], r[1]);
            let a2 = _mm_unpacklo_epi8(r[2], r[3]);
            let a3 = _mm_unpackhi_epi8(r[2], r[3]);
            let a4 = _mm_unpacklo_epi8(r[4], r[5]);
            let a5 = _mm_unpackhi_epi8(r[4], r[5]);
            let a6 = _mm_unpacklo_epi8(r[6], r[7]);
            let a7 = _mm_unpackhi_epi8(r[6], r[7]);
            // Bytes 0–3 (b0–b3) and 4–7 (b4–b7) of values 0–3, 4–7, 8–11, 12–15.
            let b0 = _mm_unpacklo_epi16(a0, a2);
            let b1 = _mm_unpackhi_epi16(a0, a2);
            let b2 = _mm_unpacklo_epi16(a1, a3);
            let b3 = _mm_unpackhi_epi16(a1, a3);
            let b4 = _mm_unpacklo_epi16(a4, a6);
            let b5 = _mm_unpackhi_epi16(a4, a6);
            let b6 = _mm_unpacklo_epi16(a5, a7);
            let b7 = _mm_unpackhi_epi16(a5, a7);
            // Values 0–1, 2–3, …, 14–15 whole.
            let c = [
                _mm_unpacklo_epi32(b0, b4),
                _mm_unpackhi_epi32(b0, b4),
                _mm_unpacklo_epi32(b1, b5),
                _mm_unpackhi_epi32(b1, b5),
                _mm_unpacklo_epi32(b2, b6),
                _mm_unpackhi_epi32(b2, b6),
                _mm_unpacklo_epi32(b3, b7),
                _mm_unpackhi_epi32(b3, b7),
            ];
            for (k, v) in c.iter().enumerate() {
                _mm_storeu_si128(out.as_mut_ptr().add(i + 2 * k).cast(), *v);
            }
        }
        i += 16;
    }
    whole
}

/// The floats of one page's four byte streams `src` (`4 × out.len()` bytes), into `out`:
/// [`join_streams`] for f32.
fn join_streams_f32(src: &[u8], out: &mut [f32]) {
    let n = out.len();
    assert_eq!(src.len(), 4 * n, "four streams of the values' length");
    #[cfg(target_arch = "x86_64")]
    let done = join_sixteen_f32_at_a_time(src, out);
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for (i, v) in out.iter_mut().enumerate().skip(done) {
        *v = f32::from_le_bytes(std::array::from_fn(|j| src[j * n + i]));
    }
}

/// [`join_streams_f32`] sixteen values at a time (SSE2): two rounds of unpacking (bytes,
/// then pairs). Returns how many it joined (a multiple of 16).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
fn join_sixteen_f32_at_a_time(src: &[u8], out: &mut [f32]) -> usize {
    use std::arch::x86_64::{
        __m128i, _mm_loadu_si128, _mm_storeu_si128, _mm_unpackhi_epi8, _mm_unpackhi_epi16,
        _mm_unpacklo_epi8, _mm_unpacklo_epi16,
    };
    let n = out.len();
    assert_eq!(src.len(), 4 * n, "four streams of the values' length");
    let whole = n - n % 16;
    let mut i = 0;
    while i < whole {
        // SAFETY: SSE2 is in every x86-64 CPU. Each load reads bytes `j n + i` to
        // `j n + i + 15` of `src` (4 n long), within it as `i + 16 ≤ n`; each store writes
        // four of `out`'s values `i..i + 16`, within it; unaligned loads and stores.
        unsafe {
            let r: [__m128i; 4] =
                std::array::from_fn(|j| _mm_loadu_si128(src.as_ptr().add(j * n + i).cast()));
            // Bytes 0 and 1, 2 and 3 of values 0–7 (lo) and 8–15 (hi).
            let a0 = _mm_unpacklo_epi8(r[0], r[1]);
            let a1 = _mm_unpackhi_epi8(r[0], r[1]);
            let a2 = _mm_unpacklo_epi8(r[2], r[3]);
            let a3 = _mm_unpackhi_epi8(r[2], r[3]);
            // Values 0–3, 4–7, 8–11, 12–15 whole.
            let c = [
                _mm_unpacklo_epi16(a0, a2),
                _mm_unpackhi_epi16(a0, a2),
                _mm_unpacklo_epi16(a1, a3),
                _mm_unpackhi_epi16(a1, a3),
            ];
            for (k, v) in c.iter().enumerate() {
                _mm_storeu_si128(out.as_mut_ptr().add(i + 4 * k).cast(), *v);
            }
        }
        i += 16;
    }
    whole
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use arrow::array::{ArrayRef, FixedSizeListArray, Float64Array, Int64Array, RecordBatch};
    use arrow::datatypes::{DataType, Field, Schema};

    use super::*;
    use crate::parquet_io::{ParquetSink, read_batches};
    use crate::tables::{f64_column, vec3_column};

    /// The item of a list column of three doubles a row.
    fn item() -> Arc<Field> {
        Arc::new(Field::new("item", DataType::Float64, false))
    }

    /// A list column `name` of three doubles a row.
    fn triples_field(name: &str) -> Field {
        Field::new(name, DataType::FixedSizeList(item(), 3), false)
    }

    /// The rows of three of `v` (its values one row after the other).
    fn triples(v: Vec<f64>) -> ArrayRef {
        Arc::new(FixedSizeListArray::new(
            item(),
            3,
            Arc::new(Float64Array::from(v)),
            None,
        ))
    }

    /// Doubles of every kind: signs, tiny and huge, infinities, NaN with a payload.
    fn values(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|k| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                match k % 97 {
                    0 => f64::NAN,
                    1 => f64::from_bits(0x7ff8_dead_beef_0001),
                    2 => f64::NEG_INFINITY,
                    3 => -0.0,
                    4 => 5e-324,
                    _ => f64::from_bits(s),
                }
            })
            .collect()
    }

    /// The streams joined sixteen at a time and one at a time are the values, for every
    /// length about a multiple of sixteen.
    #[test]
    fn joined_streams_are_the_values() {
        for n in 0..70 {
            let v = values(n, 3 + n as u64);
            let mut src = vec![0u8; 8 * n];
            for (i, x) in v.iter().enumerate() {
                for (j, b) in x.to_le_bytes().into_iter().enumerate() {
                    src[j * n + i] = b;
                }
            }
            let mut out = vec![0.0; n];
            join_streams(&src, &mut out);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out), bits(&v), "{n}");
            // The same values' f32 bits as floats of four streams.
            let w: Vec<f32> = v
                .iter()
                .map(|x| f32::from_bits(x.to_bits() as u32))
                .collect();
            let mut src = vec![0u8; 4 * n];
            for (i, x) in w.iter().enumerate() {
                for (j, b) in x.to_le_bytes().into_iter().enumerate() {
                    src[j * n + i] = b;
                }
            }
            let mut out = vec![0.0f32; n];
            join_streams_f32(&src, &mut out);
            let bits32 = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits32(&out), bits32(&w), "{n} f32");
        }
    }

    /// Rows taken from values cut anywhere (a page shorter than a row, pages ending
    /// mid-row) are the values' rows; a row left open gives none.
    #[test]
    fn rows_are_taken_across_any_cuts() {
        let v: Vec<f64> = (0..30).map(f64::from).collect();
        let want: Vec<[f64; 3]> = v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        for cuts in [
            vec![30],
            vec![1, 29],
            vec![2, 2, 2, 24],
            vec![4, 1, 1, 0, 7, 17],
            vec![3, 3, 24],
            vec![29, 1],
        ] {
            let mut rows = Rows::<3>::with_capacity(0);
            let mut at = 0;
            for n in &cuts {
                rows.take(&v[at..at + n]);
                at += n;
            }
            assert_eq!(rows.finish(), Some(want.clone()), "{cuts:?}");
        }
        let mut open = Rows::<3>::with_capacity(0);
        open.take(&v[..29]);
        assert_eq!(open.finish(), None);
    }

    /// A table's double column and list of three, over several pages and row groups, read
    /// here are what Arrow reads, bit for bit; other layouts give none.
    #[test]
    fn the_columns_read_here_are_arrows() {
        let dir = tempfile::tempdir().unwrap();
        let schema = Arc::new(Schema::new(vec![
            Field::new("t", DataType::Int64, false),
            Field::new("x", DataType::Float64, false),
            triples_field("v"),
            Field::new("maybe", DataType::Float64, true),
        ]));
        let path = dir.path().join("t.parquet");
        // Pages of about a MiB and row groups of 100 000 rows: several of each.
        let mut sink = ParquetSink::create_in_row_groups(&path, schema.clone(), 100_000).unwrap();
        let mut want_x = Vec::new();
        let mut want_v = Vec::new();
        for (b, rows) in [70_000usize, 150_001, 3].into_iter().enumerate() {
            let x = values(rows, 11 + b as u64);
            let v = values(3 * rows, 17 + b as u64);
            let maybe: Float64Array = (0..rows)
                .map(|k| (k % 5 != 0).then_some(k as f64))
                .collect();
            let batch = RecordBatch::try_new(
                schema.clone(),
                vec![
                    Arc::new(Int64Array::from_iter_values(0..rows as i64)) as ArrayRef,
                    Arc::new(Float64Array::from(x.clone())),
                    triples(v.clone()),
                    Arc::new(maybe),
                ],
            )
            .unwrap();
            sink.write(&batch).unwrap();
            want_x.extend(x);
            want_v.extend(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        }
        sink.finish().unwrap();
        let (_, batches) = read_batches(&path).unwrap();
        let arrow_x: Vec<f64> = batches
            .iter()
            .flat_map(|b| f64_column(b, "x").unwrap().to_vec())
            .collect();
        let arrow_v: Vec<[f64; 3]> = batches
            .iter()
            .flat_map(|b| vec3_column(b, "v").unwrap())
            .collect();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&arrow_x), bits(&want_x));
        let x = read_split_doubles(&path, "x", 1).unwrap().unwrap();
        assert_eq!(bits(&x), bits(&arrow_x));
        // Within the bound, the metadata's count is the room made, once.
        let pages = Pages::open::<f64>(&path, "x", 1).unwrap().unwrap();
        assert_eq!(pages.room_for_rows(1), x.len());
        assert_eq!(x.capacity(), x.len());
        let v = read_split_vec3(&path, "v").unwrap().unwrap();
        assert_eq!(
            bits(v.as_flattened()),
            bits(arrow_v.as_flattened()),
            "the lists"
        );
        // Page by page, the doubles and (below) floats.
        let mut paged = Vec::new();
        let whole = for_each_split_page::<f64>(&path, "x", |first, values| {
            assert_eq!(first, paged.len());
            paged.extend_from_slice(values);
        })
        .unwrap();
        assert!(whole);
        assert_eq!(bits(&paged), bits(&arrow_x));
        assert!(!for_each_split_page::<f32>(&path, "x", |_, _| {}).unwrap());
        // Not this layout: an integer column, a nullable one, a list read as scalars or
        // with another length, a column not there.
        assert_eq!(read_split_doubles(&path, "t", 1).unwrap(), None);
        assert_eq!(read_split_doubles(&path, "maybe", 1).unwrap(), None);
        assert_eq!(read_split_doubles(&path, "v.list.item", 1).unwrap(), None);
        assert_eq!(read_split_doubles(&path, "v.list.item", 2).unwrap(), None);
        assert_eq!(read_split_doubles(&path, "x", 3).unwrap(), None);
        assert_eq!(read_split_doubles(&path, "nothing", 1).unwrap(), None);
        // A table written by Arrow's own writer (not the tables' encodings: PLAIN).
        let plain = dir.path().join("plain.parquet");
        write_plain(&plain, &batches[0]);
        assert_eq!(read_split_doubles(&plain, "x", 1).unwrap(), None);
        // Not Parquet: an error naming the file.
        let junk = dir.path().join("junk.parquet");
        std::fs::write(&junk, b"not parquet at all").unwrap();
        let e = read_split_doubles(&junk, "x", 1).unwrap_err();
        assert!(e.to_string().contains("junk.parquet"), "{e}");
    }

    /// Columns that compress to fewer bytes than values are read into vectors of their
    /// exact length (no room left over from growing past the metadata's count), and room
    /// grows by doubling up to the count, or to what is asked beyond it.
    #[test]
    fn columns_read_have_no_room_left_over() {
        let dir = tempfile::tempdir().unwrap();
        let schema = Arc::new(Schema::new(vec![
            Field::new("x", DataType::Float64, false),
            triples_field("v"),
        ]));
        let path = dir.path().join("c.parquet");
        let rows = 600_001;
        let mut sink = ParquetSink::create_in_row_groups(&path, schema.clone(), 250_000).unwrap();
        // A speed held for long stretches: a few bytes a value once compressed.
        let x: Vec<f64> = (0..rows).map(|k| 0.25 * (k / 5000) as f64).collect();
        let v: Vec<f64> = (0..3 * rows).map(|k| (k / 9000) as f64).collect();
        let batch = RecordBatch::try_new(
            schema,
            vec![
                Arc::new(Float64Array::from(x.clone())) as ArrayRef,
                triples(v.clone()),
            ],
        )
        .unwrap();
        sink.write(&batch).unwrap();
        sink.finish().unwrap();
        let file_bytes = std::fs::metadata(&path).unwrap().len() as usize;
        assert!(file_bytes < rows / 4, "{file_bytes} bytes");
        // Denser than the bound: room for four rows a byte up front, the rest grown.
        let pages = Pages::open::<f64>(&path, "x", 1).unwrap().unwrap();
        assert_eq!(pages.room_for_rows(1), 4 * file_bytes);
        assert_eq!(pages.room_for_rows(3), 12 * file_bytes);
        let read = read_split_doubles(&path, "x", 1).unwrap().unwrap();
        assert_eq!(read, x);
        assert_eq!(read.capacity(), rows);
        let read = read_split_vec3(&path, "v").unwrap().unwrap();
        assert_eq!(read.as_flattened(), v);
        assert_eq!(read.capacity(), rows);
        let mut grown: Vec<u8> = Vec::with_capacity(10);
        reserve_up_to(&mut grown, 11, 100);
        assert_eq!(grown.capacity(), 20);
        reserve_up_to(&mut grown, 21, 30);
        assert_eq!(grown.capacity(), 30);
        reserve_up_to(&mut grown, 45, 30);
        assert_eq!(grown.capacity(), 45);
    }

    /// A table's f32 column read page by page is what Arrow reads, bit for bit.
    #[test]
    fn float_columns_page_by_page_are_arrows() {
        use arrow::array::Float32Array;
        let dir = tempfile::tempdir().unwrap();
        let schema = Arc::new(Schema::new(vec![
            Field::new("h", DataType::Float32, false),
            Field::new("maybe", DataType::Float32, true),
        ]));
        let path = dir.path().join("f.parquet");
        let mut sink = ParquetSink::create_in_row_groups(&path, schema.clone(), 300_000).unwrap();
        let h: Vec<f32> = values(700_001, 5)
            .iter()
            .map(|x| f32::from_bits((x.to_bits() >> 17) as u32))
            .collect();
        let maybe: Float32Array = (0..h.len()).map(|k| (k % 3 == 0).then_some(1.0)).collect();
        let batch = RecordBatch::try_new(
            schema,
            vec![
                Arc::new(Float32Array::from(h.clone())) as ArrayRef,
                Arc::new(maybe),
            ],
        )
        .unwrap();
        sink.write(&batch).unwrap();
        sink.finish().unwrap();
        let mut paged: Vec<f32> = Vec::new();
        let mut pages = 0;
        assert!(
            for_each_split_page::<f32>(&path, "h", |first, values| {
                assert_eq!(first, paged.len());
                paged.extend_from_slice(values);
                pages += 1;
            })
            .unwrap()
        );
        assert!(pages > 3, "{pages} pages");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&paged), bits(&h));
        assert!(!for_each_split_page::<f32>(&path, "maybe", |_, _| {}).unwrap());
        assert!(!for_each_split_page::<f64>(&path, "h", |_, _| {}).unwrap());
    }

    /// `batch` written by Arrow's writer with its default (dictionary, PLAIN) encodings.
    fn write_plain(path: &Path, batch: &RecordBatch) {
        let file = std::fs::File::create(path).unwrap();
        let mut w = parquet::arrow::ArrowWriter::try_new(file, batch.schema(), None).unwrap();
        w.write(batch).unwrap();
        w.close().unwrap();
    }
}
