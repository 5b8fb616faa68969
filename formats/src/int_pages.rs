//! Flat integer columns, required or nullable, whose pages are encoded here: the pages,
//! the chunk and its metadata parquet-rs's column writer makes with the tables'
//! settings, byte for byte, in a fraction of its time. The encoding is the column's
//! [`IntEncoder`]: `delta_pages`' DELTA_BINARY_PACKED for 64-bit integers, `plain_pages`'
//! PLAIN for 32-bit ones (and the narrower ones stored as such).
//!
//! What stays the crate's: where pages are cut (after each batch of `write_batch_size`
//! rows, once the page holds `data_page_row_count_limit` rows or its values' encoded
//! size reaches `data_page_size_limit` bytes), each page's header and offset in the
//! chunk, the chunk's metadata and offset index, all built by its public types
//! ([`ChunkLedger`]); the pages compressed as `split_pages` compresses them. Only the
//! settings the tables use are taken ([`IntColumn::new`]); any other column goes to the
//! crate's writer. `parquet_io`'s tests compare whole files with `ArrowWriter`'s.
//!
//! A nullable column (the odometer's pulse count, null where a text log has none) goes
//! the Arrow writer's way otherwise: each batch's definition levels and the indices of
//! its non-null values computed, the values gathered by them, then each level and value
//! through the crate's encoders, 38 M of the odometer table's 69 M instructions in a
//! 40-minute ingest (session 94). Here its levels are kept as bytes for the page being
//! filled and encoded once the page is cut (as the run of ones the encoder's port writes
//! when none is null), and its non-null values go to the same encoder as a required
//! column's.

use std::borrow::Cow;

use arrow::array::{Array, ArrayRef};
use arrow::buffer::NullBuffer;
use parquet::basic::{Encoding, Type as PhysicalType};
use parquet::column::writer::ColumnCloseResult;
use parquet::errors::ParquetError;
use parquet::file::properties::WriterPropertiesPtr;
use parquet::file::statistics::{Statistics, ValueStatistics};
use parquet::schema::types::ColumnDescPtr;

use crate::chunk_ledger::{ChunkLedger, PageSettings};
use crate::parquet_columns::{ChunkPages, DirectShape, plain_values};
use crate::split_pages::{compressed_page, rle_constant, rle_hybrid};

/// An integer of a column's physical type, ordered for its chunk's bounds.
pub(crate) trait IntValue: Copy + Ord + std::ops::BitXor<Output = Self> {
    /// The least and greatest value; the least is also the sign bit alone, whose flip
    /// makes an unsigned order a signed one.
    const MIN: Self;
    const MAX: Self;
    const ZERO: Self;
    /// A chunk's statistics: its bounds, its nulls, the deprecated min and max fields
    /// written too when the column's order is signed (as the crate writes them).
    fn statistics(bounds: Option<(Self, Self)>, nulls: u64, signed: bool) -> Statistics;
}

/// [`IntValue`] for `$t`.
macro_rules! int_value {
    ($t:ty) => {
        impl IntValue for $t {
            const MIN: Self = <$t>::MIN;
            const MAX: Self = <$t>::MAX;
            const ZERO: Self = 0;
            fn statistics(bounds: Option<(Self, Self)>, nulls: u64, signed: bool) -> Statistics {
                let (min, max) = bounds.unzip();
                ValueStatistics::new(min, max, None, Some(nulls), false)
                    .with_backwards_compatible_min_max(signed)
                    .into()
            }
        }
    };
}

int_value!(i32);
int_value!(i64);

/// A page's value encoder, as the crate's for its encoding, state for state.
pub(crate) trait IntEncoder: Default {
    /// The column's physical values.
    type Value: IntValue;
    /// The column's physical type.
    const PHYSICAL: PhysicalType;
    /// The encoding the file's settings must ask of the column.
    const ENCODING: Encoding;
    /// The values of `array` (of an Arrow type this encoding takes) as the Arrow writer
    /// converts them to the physical type, null slots included.
    fn values(array: &dyn Array) -> Result<Cow<'_, [Self::Value]>, ParquetError>;
    /// Takes `values` into the page.
    fn put(&mut self, values: &[Self::Value]);
    /// The page's values' encoded size so far, as the crate estimates it to cut pages.
    fn estimated_bytes(&self) -> usize;
    /// Appends the page's encoded values to `out`, and empties the encoder.
    fn finish_into(&mut self, out: &mut Vec<u8>);
}

/// The least and greatest value, in the column's order (unsigned for the unsigned
/// types).
#[derive(Debug, Clone, Copy)]
struct Bounds<T> {
    unsigned: bool,
    min_max: Option<(T, T)>,
}

impl<T: IntValue> Bounds<T> {
    fn push(&mut self, values: &[T]) {
        // In the order's key: an unsigned value's bits flipped at the top compare as a
        // signed one's.
        let flip = if self.unsigned { T::MIN } else { T::ZERO };
        let (mut lo, mut hi) = match self.min_max {
            Some((lo, hi)) => (lo ^ flip, hi ^ flip),
            None => (T::MAX, T::MIN),
        };
        for &v in values {
            lo = lo.min(v ^ flip);
            hi = hi.max(v ^ flip);
        }
        if !values.is_empty() || self.min_max.is_some() {
            self.min_max = Some((lo ^ flip, hi ^ flip));
        }
    }
}

/// A flat integer column, required or nullable, whose pages `E` encodes (see the
/// module's notes).
pub(crate) struct IntColumn<E: IntEncoder> {
    descr: ColumnDescPtr,
    settings: PageSettings,
    encoder: E,
    /// Rows (values, nulls among them) in the page being filled.
    page_values: usize,
    /// A nullable column's definition levels of the page being filled (`None` for a
    /// required column), and how many of them are nulls. Kept only once the page has a
    /// null: the rows before it, and any after it not yet listed, are valid.
    page_levels: Option<Vec<u8>>,
    page_nulls: usize,
    /// The chunk's nulls so far.
    nulls: u64,
    /// A batch's non-null values, gathered.
    gathered: Vec<E::Value>,
    bounds: Bounds<E::Value>,
    /// The chunk's pages so far.
    chunk: ChunkLedger,
}

impl<E: IntEncoder> IntColumn<E> {
    /// A writer of the leaf `descr` with the file's `props`, or `None` unless the column is
    /// a flat one of `E`'s physical type, required ([`DirectShape::Flat`]) or nullable
    /// ([`DirectShape::Nullable`]), and its settings are the tables': version 1 pages, no
    /// dictionary, `E`'s encoding, chunk statistics, no bloom filter, zstd.
    pub(crate) fn new(
        descr: ColumnDescPtr,
        props: WriterPropertiesPtr,
        shape: DirectShape,
    ) -> Option<Self> {
        let max_def = match shape {
            DirectShape::Flat => 0,
            DirectShape::Nullable => 1,
            DirectShape::List { .. } => return None,
        };
        if descr.max_def_level() != max_def || descr.max_rep_level() != 0 {
            return None;
        }
        let settings = PageSettings::of(&descr, &props, E::PHYSICAL, E::ENCODING)?;
        let unsigned = !descr.sort_order().is_signed();
        Some(Self {
            chunk: ChunkLedger::new(descr.clone(), &props, E::ENCODING, settings.zstd),
            descr,
            settings,
            encoder: E::default(),
            page_values: 0,
            page_levels: (max_def == 1).then(Vec::new),
            page_nulls: 0,
            nulls: 0,
            gathered: Vec::new(),
            bounds: Bounds {
                unsigned,
                min_max: None,
            },
        })
    }

    /// Encodes the values of `column` (of an Arrow type `E` takes, with nulls only in a
    /// nullable column).
    pub(crate) fn write_array(&mut self, column: &ArrayRef) -> Result<(), ParquetError> {
        if self.page_levels.is_some() {
            let nulls = column.logical_nulls();
            return match nulls.filter(|n| n.null_count() > 0) {
                Some(nulls) => self.write_with_nulls(&E::values(column)?, &nulls),
                None => self.write(&E::values(column)?),
            };
        }
        self.write(&E::values(plain_values(column, DirectShape::Flat)?)?)
    }

    /// Encodes `values`, none of them null: batches of `write_batch_size` values from its
    /// first, a page cut after the batch that fills it.
    fn write(&mut self, values: &[E::Value]) -> Result<(), ParquetError> {
        self.bounds.push(values);
        for batch in values.chunks(self.settings.batch) {
            self.encoder.put(batch);
            self.end_batch(batch.len())?;
        }
        Ok(())
    }

    /// Encodes the rows of a nullable column, `values` where `nulls` says they are valid:
    /// batches of `write_batch_size` rows (levels) from its first, each batch's non-null
    /// values gathered, a page cut after the batch that fills it.
    fn write_with_nulls(
        &mut self,
        values: &[E::Value],
        nulls: &NullBuffer,
    ) -> Result<(), ParquetError> {
        let batch = self.settings.batch;
        let mut gathered = std::mem::take(&mut self.gathered);
        let mut start = 0;
        while start < values.len() {
            let end = values.len().min(start + batch);
            gathered.clear();
            let levels = self.page_levels.get_or_insert_with(Vec::new);
            levels.resize(self.page_values, 1);
            for (k, &v) in values.iter().enumerate().take(end).skip(start) {
                let valid = nulls.is_valid(k);
                levels.push(u8::from(valid));
                if valid {
                    gathered.push(v);
                }
            }
            self.page_nulls += end - start - gathered.len();
            self.bounds.push(&gathered);
            self.encoder.put(&gathered);
            self.end_batch(end - start)?;
            start = end;
        }
        self.gathered = gathered;
        Ok(())
    }

    /// Counts a batch of `rows` rows into the page, and cuts the page when it is full: as
    /// parquet-rs does, by its rows (nulls among them) or its values' encoded size.
    fn end_batch(&mut self, rows: usize) -> Result<(), ParquetError> {
        self.page_values += rows;
        if self.page_values >= self.settings.page_rows
            || self.encoder.estimated_bytes() >= self.settings.page_bytes
        {
            self.page()?;
        }
        Ok(())
    }

    /// Writes the page of the values taken since the last: a nullable column's definition
    /// levels, then the values.
    fn page(&mut self) -> Result<(), ParquetError> {
        let n = std::mem::take(&mut self.page_values);
        let nulls = std::mem::take(&mut self.page_nulls);
        let levels = match &mut self.page_levels {
            Some(levels) if nulls == 0 => {
                levels.clear();
                rle_constant(n, 1)
            }
            Some(levels) => {
                levels.resize(n, 1);
                let encoded = rle_hybrid(levels, 1);
                levels.clear();
                encoded
            }
            None => Vec::new(),
        };
        self.nulls += nulls as u64;
        let level = self.chunk.zstd().compression_level();
        let encoder = &mut self.encoder;
        let (buf, uncompressed) = compressed_page(level, |out| {
            out.extend_from_slice(&levels);
            encoder.finish_into(out);
        })?;
        self.chunk.push(buf, uncompressed, n, n, nulls)
    }

    /// Writes the last page and returns the chunk's pages and what the row group records
    /// of them.
    pub(crate) fn close(mut self) -> Result<(ChunkPages, ColumnCloseResult), ParquetError> {
        if self.page_values > 0 {
            self.page()?;
        }
        let signed = self.descr.sort_order().is_signed();
        self.chunk.close(E::Value::statistics(
            self.bounds.min_max,
            self.nulls,
            signed,
        ))
    }
}
