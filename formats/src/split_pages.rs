//! Required flat float columns written as BYTE_STREAM_SPLIT pages: the pages, the chunk
//! and its metadata parquet-rs's column writer makes with the tables' settings, byte for
//! byte, in a fraction of its time.
//!
//! The crate's writer copies every value into its encoder, finds the bounds of each batch
//! of 1 024 values one value at a time (a NaN test and two comparisons, each dispatched on
//! the column's type), splits each page's bytes into streams one byte at a time (a bounds
//! check on each), and copies the compressed page twice more. Here a page's values are
//! split straight from the caller's array when a page lies within it (else from the
//! values kept since the last page), sixteen at a time by SSE2's byte unpacking (the
//! inverse of [`crate::split_doubles`]' join); the bounds are kept in eight lanes; the
//! pages are compressed by a zstd context the thread keeps (the same library and level:
//! the same bytes).
//!
//! What stays the crate's: where pages are cut (after each batch of
//! `write_batch_size` values, once the page holds `data_page_row_count_limit` rows or
//! `data_page_size_limit` bytes), each page's header and offset in the chunk, the chunk's
//! metadata and offset index, all built by its public types. Only the settings the tables
//! use are taken ([`SplitColumn::new`]); any other column goes to the crate's writer.
//! `parquet_io`'s tests compare whole files with `ArrowWriter`'s.

use std::cell::RefCell;

use bytes::Bytes;
use parquet::basic::{Compression, Encoding, EncodingMask, PageType, Type as PhysicalType};
use parquet::column::page::{CompressedPage, Page};
use parquet::column::writer::ColumnCloseResult;
use parquet::errors::ParquetError;
use parquet::file::metadata::{ColumnChunkMetaData, OffsetIndexBuilder, PageEncodingStats};
use parquet::file::properties::{EnabledStatistics, WriterPropertiesPtr, WriterVersion};
use parquet::file::statistics::{Statistics, ValueStatistics};
use parquet::schema::types::ColumnDescPtr;

use crate::parquet_columns::ChunkPages;

/// A float type written BYTE_STREAM_SPLIT: its Parquet type, its statistics, and how a
/// page's values split into byte streams.
pub(crate) trait PageFloat: Copy + PartialOrd + bytemuck::Pod {
    /// Its Parquet physical type.
    const PHYSICAL: PhysicalType;
    /// Bytes a value (and streams a page).
    const SIZE: usize;
    /// +∞ and −∞: the bounds of no value.
    const INFINITY: Self;
    const NEG_INFINITY: Self;
    /// Zero of either sign: a bound the format writes as −0 (a minimum) or +0 (a maximum).
    fn is_zero(self) -> bool;
    /// −0 and +0.
    const NEG_ZERO: Self;
    const ZERO: Self;
    /// The chunk statistics parquet-rs's writer makes of these bounds and no nulls.
    fn statistics(min: Option<Self>, max: Option<Self>, backwards_compatible: bool) -> Statistics;
    /// The byte streams of `values` into `out` (`SIZE × values.len()` bytes): byte `j` of
    /// value `i` at `j × values.len() + i`.
    fn split(values: &[Self], out: &mut [u8]);
}

impl PageFloat for f64 {
    const PHYSICAL: PhysicalType = PhysicalType::DOUBLE;
    const SIZE: usize = 8;
    const INFINITY: f64 = f64::INFINITY;
    const NEG_INFINITY: f64 = f64::NEG_INFINITY;
    const NEG_ZERO: f64 = -0.0;
    const ZERO: f64 = 0.0;
    fn is_zero(self) -> bool {
        self == 0.0
    }
    fn statistics(min: Option<f64>, max: Option<f64>, backwards_compatible: bool) -> Statistics {
        ValueStatistics::new(min, max, None, Some(0), false)
            .with_backwards_compatible_min_max(backwards_compatible)
            .into()
    }
    fn split(values: &[f64], out: &mut [u8]) {
        split_streams::<8>(bytemuck::cast_slice(values), out);
    }
}

impl PageFloat for f32 {
    const PHYSICAL: PhysicalType = PhysicalType::FLOAT;
    const SIZE: usize = 4;
    const INFINITY: f32 = f32::INFINITY;
    const NEG_INFINITY: f32 = f32::NEG_INFINITY;
    const NEG_ZERO: f32 = -0.0;
    const ZERO: f32 = 0.0;
    fn is_zero(self) -> bool {
        self == 0.0
    }
    fn statistics(min: Option<f32>, max: Option<f32>, backwards_compatible: bool) -> Statistics {
        ValueStatistics::new(min, max, None, Some(0), false)
            .with_backwards_compatible_min_max(backwards_compatible)
            .into()
    }
    fn split(values: &[f32], out: &mut [u8]) {
        split_streams::<4>(bytemuck::cast_slice(values), out);
    }
}

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
        let min = if min.is_zero() { T::NEG_ZERO } else { min };
        let max = if max.is_zero() { T::ZERO } else { max };
        Some((min, max))
    }
}

thread_local! {
    /// The thread's zstd context and its level (made once, reset by each compression).
    static ZSTD: RefCell<Option<(i32, zstd::bulk::Compressor<'static>)>> =
        const { RefCell::new(None) };
}

/// `src` compressed at zstd `level` into `out` (emptied first), as parquet-rs's codec
/// compresses a page: one frame by the bulk API.
fn zstd_compress(level: i32, src: &[u8], out: &mut Vec<u8>) -> Result<(), ParquetError> {
    out.clear();
    out.reserve(zstd::zstd_safe::compress_bound(src.len()));
    ZSTD.with_borrow_mut(|slot| {
        let compressor = match slot {
            Some((l, c)) if *l == level => c,
            _ => &mut slot.insert((level, zstd::bulk::Compressor::new(level)?)).1,
        };
        compressor.compress_to_buffer(src, out).map(|_| ())
    })
    .map_err(|e| ParquetError::External(Box::new(e)))
}

/// The writer settings a [`SplitColumn`] takes from the file's.
#[derive(Debug, Clone, Copy)]
struct Settings {
    /// Values encoded between checks of the page's size.
    batch: usize,
    /// A page is cut once it holds this many rows…
    page_rows: usize,
    /// … or this many bytes.
    page_bytes: usize,
    /// Zstd, at `zstd_level`.
    codec: Compression,
    zstd_level: i32,
    offset_index: bool,
}

/// A required flat float column written as BYTE_STREAM_SPLIT pages (see the module's
/// notes).
pub(crate) struct SplitColumn<T> {
    descr: ColumnDescPtr,
    settings: Settings,
    /// Values of the page being filled that came in an earlier batch.
    kept: Vec<T>,
    /// Values in the page being filled.
    page_len: usize,
    bounds: Bounds<T>,
    /// A page's streams, then its compressed bytes.
    streams: Vec<u8>,
    compressed: Vec<u8>,
    pages: ChunkPages,
    offset_index: Option<OffsetIndexBuilder>,
    page_count: i32,
    rows: u64,
    uncompressed_bytes: u64,
    compressed_bytes: u64,
    bytes_written: u64,
    first_page_offset: Option<u64>,
}

impl<T: PageFloat> SplitColumn<T> {
    /// A writer of the leaf `descr` with the file's `props`, or `None` unless the column is
    /// a required flat one of `T` and its settings are the tables': version 1 pages, no
    /// dictionary, BYTE_STREAM_SPLIT, chunk statistics, no bloom filter, zstd.
    pub(crate) fn new(descr: ColumnDescPtr, props: WriterPropertiesPtr) -> Option<Self> {
        let path = descr.path();
        let Compression::ZSTD(level) = props.compression(path) else {
            return None;
        };
        let taken = descr.physical_type() == T::PHYSICAL
            && props.statistics_enabled(path) == EnabledStatistics::Chunk
            && descr.max_def_level() == 0
            && descr.max_rep_level() == 0
            && props.writer_version() == WriterVersion::PARQUET_1_0
            && !props.dictionary_enabled(path)
            && props.encoding(path) == Some(Encoding::BYTE_STREAM_SPLIT)
            && props.bloom_filter_properties(path).is_none()
            && props.write_batch_size() > 0;
        if !taken {
            return None;
        }
        let settings = Settings {
            batch: props.write_batch_size(),
            page_rows: props.data_page_row_count_limit(),
            page_bytes: props.column_data_page_size_limit(path),
            codec: Compression::ZSTD(level),
            zstd_level: level.compression_level(),
            offset_index: !props.offset_index_disabled(),
        };
        Some(Self {
            descr,
            settings,
            kept: Vec::new(),
            page_len: 0,
            bounds: Bounds::new(),
            streams: Vec::new(),
            compressed: Vec::new(),
            pages: ChunkPages::default(),
            offset_index: settings.offset_index.then(OffsetIndexBuilder::new),
            page_count: 0,
            rows: 0,
            uncompressed_bytes: 0,
            compressed_bytes: 0,
            bytes_written: 0,
            first_page_offset: None,
        })
    }

    /// Encodes `values`, a row each: batches of `write_batch_size` from its first, a page
    /// cut after the batch that fills it.
    pub(crate) fn write(&mut self, values: &[T]) -> Result<(), ParquetError> {
        self.bounds.push(values);
        // Values of `values` from `start` on are in the page being filled.
        let mut start = 0;
        let mut end = 0;
        while end < values.len() {
            let batch = self.settings.batch.min(values.len() - end);
            end += batch;
            self.page_len += batch;
            let full = self.page_len >= self.settings.page_rows
                || self.page_len * T::SIZE >= self.settings.page_bytes;
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

    /// Writes the page of `values`.
    fn page(&mut self, values: &[T]) -> Result<(), ParquetError> {
        let n = values.len();
        let uncompressed = n * T::SIZE;
        self.streams.resize(uncompressed, 0);
        T::split(values, &mut self.streams);
        zstd_compress(
            self.settings.zstd_level,
            &self.streams,
            &mut self.compressed,
        )?;
        let buf = Bytes::copy_from_slice(&self.compressed);
        let num_values =
            u32::try_from(n).map_err(|_| ParquetError::General(format!("a page of {n} values")))?;
        let page = Page::DataPage {
            buf,
            num_values,
            encoding: Encoding::BYTE_STREAM_SPLIT,
            def_level_encoding: Encoding::RLE,
            rep_level_encoding: Encoding::RLE,
            statistics: None,
        };
        let spec = self.pages.push(CompressedPage::new(page, uncompressed))?;
        if let Some(index) = &mut self.offset_index {
            index.append_row_count(n as i64);
            index.append_unencoded_byte_array_data_bytes(None);
            let size = i32::try_from(spec.compressed_size)
                .map_err(|_| ParquetError::General("a page of more than 2 GiB".into()))?;
            index.append_offset_and_size(spec.offset as i64, size);
        }
        self.page_count += 1;
        self.rows += n as u64;
        self.uncompressed_bytes += spec.uncompressed_size as u64;
        self.compressed_bytes += spec.compressed_size as u64;
        self.bytes_written += spec.bytes_written;
        self.first_page_offset.get_or_insert(spec.offset);
        self.page_len = 0;
        Ok(())
    }

    /// Writes the last page and returns the chunk's pages and what the row group records
    /// of them.
    pub(crate) fn close(mut self) -> Result<(ChunkPages, ColumnCloseResult), ParquetError> {
        if self.page_len > 0 {
            let kept = std::mem::take(&mut self.kept);
            self.page(&kept)?;
        }
        // The levels' encoding is always listed; BYTE_STREAM_SPLIT once a page has it.
        let mut encodings = vec![Encoding::RLE];
        let mut page_stats = Vec::new();
        if self.page_count > 0 {
            encodings.push(Encoding::BYTE_STREAM_SPLIT);
            page_stats.push(PageEncodingStats {
                page_type: PageType::DATA_PAGE,
                encoding: Encoding::BYTE_STREAM_SPLIT,
                count: self.page_count,
            });
        }
        let as_i64 =
            |v: u64| i64::try_from(v).map_err(|_| ParquetError::General("a chunk past i64".into()));
        let builder = ColumnChunkMetaData::builder(self.descr.clone())
            .set_compression(self.settings.codec)
            .set_encodings_mask(EncodingMask::new_from_encodings(encodings.iter()))
            .set_page_encoding_stats(page_stats)
            .set_total_compressed_size(as_i64(self.compressed_bytes)?)
            .set_total_uncompressed_size(as_i64(self.uncompressed_bytes)?)
            .set_num_values(as_i64(self.rows)?)
            .set_data_page_offset(as_i64(self.first_page_offset.unwrap_or(0))?)
            .set_dictionary_page_offset(None);
        let bounds = self.bounds.get();
        let backwards_compatible = self.descr.sort_order().is_signed();
        let metadata = builder
            .set_statistics(T::statistics(
                bounds.map(|b| b.0),
                bounds.map(|b| b.1),
                backwards_compatible,
            ))
            .set_unencoded_byte_array_data_bytes(None)
            .set_repetition_level_histogram(None)
            .set_definition_level_histogram(None)
            .build()?;
        let close = ColumnCloseResult {
            bytes_written: self.bytes_written,
            rows_written: self.rows,
            metadata,
            bloom_filter: None,
            column_index: None,
            offset_index: self.offset_index.map(OffsetIndexBuilder::build),
        };
        Ok((self.pages, close))
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
