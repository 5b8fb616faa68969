//! Flat 64-bit integer columns, required or nullable, written as DELTA_BINARY_PACKED
//! pages: the pages, the chunk and its metadata parquet-rs's column writer makes with the
//! tables' settings, byte for byte, in a fraction of its time.
//!
//! The tables' integer columns are times, sequence numbers and counts: their deltas are
//! nearly constant, so nearly every miniblock of 64 values packs to nothing. The crate's
//! encoder still takes each value through its bit writer (a call a value, at a width of
//! zero), and its column writer finds each batch's bounds one value at a time, dispatched
//! on the column's type: 4–5 % of the ingest's CPU for its four such columns (session 93,
//! 40-minute runs). Here a block's deltas are taken in one pass, each miniblock's width
//! found by an or of its values above the least delta and packed 64 at a time, and the
//! bounds kept as the values go by. With its lists' repetition levels written without a
//! pass over them too (`split_pages`), the ingest's IMU table's thread took 7–12 % fewer
//! profile samples, its odometer table's 10–15 %.
//!
//! A nullable column (the odometer's pulse count, null where a text log has none) goes
//! the Arrow writer's way otherwise: each batch's definition levels and the indices of
//! its non-null values computed, the values gathered by them, then each level and value
//! through the crate's encoders, 38 M of the odometer table's 69 M instructions in a
//! 40-minute ingest. Here its levels are kept as bytes for the page being filled and
//! encoded once the page is cut (as the run of ones the encoder's port writes when none
//! is null), and its non-null values go to the same encoder as a required column's.
//!
//! What stays the crate's: the encoding's layout (its blocks of 256 values in four
//! miniblocks, a page's header, how the last block is padded), where pages are cut (after
//! each batch of `write_batch_size` values, once the page holds
//! `data_page_row_count_limit` rows or its encoded blocks `data_page_size_limit` bytes),
//! each page's header and offset in the chunk, the chunk's metadata and offset index, all
//! built by its public types; the pages compressed as `split_pages` compresses them.
//! Only the settings the tables use are taken ([`DeltaColumn::new`]); any other column
//! goes to the crate's writer. `parquet_io`'s tests compare whole files with
//! `ArrowWriter`'s.

use arrow::array::{Array, ArrayRef, AsArray};
use arrow::buffer::NullBuffer;
use arrow::datatypes::{DataType, Int64Type, UInt64Type};
use parquet::basic::{Compression, Encoding, Type as PhysicalType};
use parquet::column::writer::ColumnCloseResult;
use parquet::errors::ParquetError;
use parquet::file::properties::{EnabledStatistics, WriterPropertiesPtr, WriterVersion};
use parquet::file::statistics::ValueStatistics;
use parquet::schema::types::ColumnDescPtr;

use crate::chunk_ledger::ChunkLedger;
use crate::parquet_columns::{ChunkPages, DirectShape, plain_values};
use crate::split_pages::{compressed_page, put_uleb128, rle_constant, rle_hybrid};

/// Values a miniblock (the crate's for 64-bit integers).
const MINIBLOCK: usize = 64;
/// Miniblocks a block.
const MINIBLOCKS: usize = 4;
/// Values a block.
const BLOCK: usize = MINIBLOCK * MINIBLOCKS;

/// The writer settings a [`DeltaColumn`] takes from the file's.
#[derive(Debug, Clone, Copy)]
struct Settings {
    /// Values encoded between checks of the page's size.
    batch: usize,
    /// A page is cut once it holds this many rows…
    page_rows: usize,
    /// … or its blocks encoded so far this many bytes.
    page_bytes: usize,
}

/// A page's encoder: the crate's `DeltaBitPackEncoder` for 64-bit values, state for state.
#[derive(Debug, Default)]
struct PageEncoder {
    /// Values taken into the page, its first included.
    total: usize,
    /// The page's first value (in its header).
    first: i64,
    /// The last value taken (deltas are from it).
    current: i64,
    /// The block's deltas so far.
    deltas: Vec<i64>,
    /// The page's blocks, encoded.
    blocks: Vec<u8>,
}

/// `v` zigzagged, as ULEB128 (parquet-rs's `put_zigzag_vlq_int`).
fn put_zigzag_vlq(out: &mut Vec<u8>, v: i64) {
    put_uleb128(out, ((v << 1) ^ (v >> 63)) as u64);
}

/// Bits of `x`'s highest set bit (0 for 0: the crate's `num_required_bits`).
fn bits(x: u64) -> u32 {
    u64::BITS - x.leading_zeros()
}

/// `values` (`MINIBLOCK` of them, each below 2^`width`) packed `width` bits each, the first
/// in the lowest, as the crate's bit writer lays them out: `8 × width` bytes.
fn pack(out: &mut Vec<u8>, values: &[u64; MINIBLOCK], width: u32) {
    if width == 0 {
        return;
    }
    let mut acc: u128 = 0;
    let mut held = 0u32;
    for &v in values {
        acc |= u128::from(v) << held;
        held += width;
        if held >= 64 {
            out.extend_from_slice(&(acc as u64).to_le_bytes());
            acc >>= 64;
            held -= 64;
        }
    }
    // 64 values of `width` bits fill whole words.
    debug_assert_eq!(held, 0);
}

impl PageEncoder {
    /// Takes `values` into the page (the crate's `put`).
    fn put(&mut self, values: &[i64]) {
        let Some((&head, _)) = values.split_first() else {
            return;
        };
        let mut rest = if self.total == 0 {
            self.first = head;
            self.current = head;
            &values[1..]
        } else {
            values
        };
        self.total += values.len();
        while !rest.is_empty() {
            // The block's next deltas: each value less the one before it (the first less
            // the last value taken), in one pass the compiler vectorizes.
            let take = rest.len().min(BLOCK - self.deltas.len());
            let (now, later) = rest.split_at(take);
            self.deltas.push(now[0].wrapping_sub(self.current));
            self.deltas
                .extend(now[1..].iter().zip(now).map(|(b, a)| b.wrapping_sub(*a)));
            self.current = now[take - 1];
            if self.deltas.len() == BLOCK {
                self.flush_block();
            }
            rest = later;
        }
    }

    /// Encodes the block's deltas (up to [`BLOCK`]) into the page's blocks (the crate's
    /// `flush_block_values`): the least delta, each miniblock's width, the miniblocks
    /// above the least packed at their widths, the last one padded with zeros; a
    /// miniblock past the deltas has a width of 0 and no bytes.
    fn flush_block(&mut self) {
        let deltas = &self.deltas;
        let Some(&min) = deltas.iter().min() else {
            return;
        };
        put_zigzag_vlq(&mut self.blocks, min);
        let widths_at = self.blocks.len();
        self.blocks.extend_from_slice(&[0; MINIBLOCKS]);
        for (i, mini) in deltas.chunks(MINIBLOCK).enumerate() {
            let mut above = [0u64; MINIBLOCK];
            let mut widest = 0u64;
            for (a, &d) in above.iter_mut().zip(mini) {
                *a = d.wrapping_sub(min) as u64;
                widest |= *a;
            }
            // The widest value has the most bits: an or of all has as many.
            let width = bits(widest);
            self.blocks[widths_at + i] = width as u8;
            pack(&mut self.blocks, &above, width);
        }
        self.deltas.clear();
    }

    /// The page's encoded values (the crate's `flush_buffer`): the last block, then the
    /// header (block size, miniblocks, values, first value) before the blocks; the encoder
    /// is left empty.
    fn finish_into(&mut self, out: &mut Vec<u8>) {
        self.flush_block();
        put_uleb128(out, BLOCK as u64);
        put_uleb128(out, MINIBLOCKS as u64);
        put_uleb128(out, self.total as u64);
        put_zigzag_vlq(out, self.first);
        out.extend_from_slice(&self.blocks);
        self.blocks.clear();
        self.total = 0;
        self.first = 0;
        self.current = 0;
    }
}

/// The least and greatest value, in the column's order (unsigned for `u64`).
#[derive(Debug, Clone, Copy)]
struct Bounds {
    unsigned: bool,
    min_max: Option<(i64, i64)>,
}

impl Bounds {
    fn push(&mut self, values: &[i64]) {
        // In the order's key: a u64's bits flipped at the top compare as an i64.
        let flip = if self.unsigned { i64::MIN } else { 0 };
        let (mut lo, mut hi) = match self.min_max {
            Some((lo, hi)) => (lo ^ flip, hi ^ flip),
            None => (i64::MAX, i64::MIN),
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

/// A flat 64-bit integer column, required or nullable, written as DELTA_BINARY_PACKED
/// pages (see the module's notes).
pub(crate) struct DeltaColumn {
    descr: ColumnDescPtr,
    settings: Settings,
    encoder: PageEncoder,
    /// Rows (values, nulls among them) in the page being filled.
    page_values: usize,
    /// A nullable column's definition levels of the page being filled (`None` for a
    /// required column), and how many of them are nulls.
    page_levels: Option<Vec<u8>>,
    page_nulls: usize,
    /// The chunk's nulls so far.
    nulls: u64,
    /// A batch's non-null values, gathered.
    gathered: Vec<i64>,
    bounds: Bounds,
    /// The chunk's pages so far.
    chunk: ChunkLedger,
}

impl DeltaColumn {
    /// A writer of the leaf `descr` with the file's `props`, or `None` unless the column is
    /// a flat 64-bit integer one, required ([`DirectShape::Flat`]) or nullable
    /// ([`DirectShape::Nullable`]), and its settings are the tables': version 1 pages, no
    /// dictionary, DELTA_BINARY_PACKED, chunk statistics, no bloom filter, zstd.
    pub(crate) fn new(
        descr: ColumnDescPtr,
        props: WriterPropertiesPtr,
        shape: DirectShape,
    ) -> Option<Self> {
        let path = descr.path();
        let Compression::ZSTD(level) = props.compression(path) else {
            return None;
        };
        let max_def = match shape {
            DirectShape::Flat => 0,
            DirectShape::Nullable => 1,
            DirectShape::List { .. } => return None,
        };
        let taken = descr.max_def_level() == max_def
            && descr.max_rep_level() == 0
            && descr.physical_type() == PhysicalType::INT64
            && props.statistics_enabled(path) == EnabledStatistics::Chunk
            && props.writer_version() == WriterVersion::PARQUET_1_0
            && !props.dictionary_enabled(path)
            && props.encoding(path) == Some(Encoding::DELTA_BINARY_PACKED)
            && props.bloom_filter_properties(path).is_none()
            && props.write_batch_size() > 0;
        if !taken {
            return None;
        }
        let settings = Settings {
            batch: props.write_batch_size(),
            page_rows: props.data_page_row_count_limit(),
            page_bytes: props.column_data_page_size_limit(path),
        };
        let unsigned = !descr.sort_order().is_signed();
        Some(Self {
            chunk: ChunkLedger::new(descr.clone(), &props, Encoding::DELTA_BINARY_PACKED, level),
            descr,
            settings,
            encoder: PageEncoder {
                deltas: Vec::with_capacity(BLOCK),
                ..PageEncoder::default()
            },
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

    /// Encodes the values of `column` (an `Int64` or a `UInt64` array, with nulls only in
    /// a nullable column; a u64's bits stored as an i64's, as the Arrow writer stores
    /// them).
    pub(crate) fn write_array(&mut self, column: &ArrayRef) -> Result<(), ParquetError> {
        if self.page_levels.is_some() {
            let nulls = column.logical_nulls();
            return match nulls.filter(|n| n.null_count() > 0) {
                Some(nulls) => self.write_with_nulls(wide_integers(column)?, &nulls),
                None => self.write(wide_integers(column)?),
            };
        }
        self.write(wide_integers(plain_values(column, DirectShape::Flat)?)?)
    }

    /// Encodes `values`, none of them null: batches of `write_batch_size` values from its
    /// first, a page cut after the batch that fills it.
    fn write(&mut self, values: &[i64]) -> Result<(), ParquetError> {
        self.bounds.push(values);
        for batch in values.chunks(self.settings.batch) {
            self.encoder.put(batch);
            if let Some(levels) = &mut self.page_levels {
                levels.resize(levels.len() + batch.len(), 1);
            }
            self.end_batch(batch.len())?;
        }
        Ok(())
    }

    /// Encodes the rows of a nullable column, `values` where `nulls` says they are valid:
    /// batches of `write_batch_size` rows (levels) from its first, each batch's non-null
    /// values gathered, a page cut after the batch that fills it.
    fn write_with_nulls(&mut self, values: &[i64], nulls: &NullBuffer) -> Result<(), ParquetError> {
        let batch = self.settings.batch;
        let mut gathered = std::mem::take(&mut self.gathered);
        let mut start = 0;
        while start < values.len() {
            let end = values.len().min(start + batch);
            gathered.clear();
            let levels = self.page_levels.get_or_insert_with(Vec::new);
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
            || self.encoder.blocks.len() >= self.settings.page_bytes
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
        let (min, max) = self.bounds.min_max.unzip();
        self.chunk.close(
            ValueStatistics::new(min, max, None, Some(self.nulls), false)
                .with_backwards_compatible_min_max(self.descr.sort_order().is_signed())
                .into(),
        )
    }
}

/// The values of `values` (an `Int64` or a `UInt64` array; a u64's bits as an i64's, as
/// the Arrow writer stores them), null slots included.
fn wide_integers(values: &dyn Array) -> Result<&[i64], ParquetError> {
    let values: &[i64] = match values.data_type() {
        DataType::Int64 => values.as_primitive::<Int64Type>().values(),
        DataType::UInt64 => values
            .as_primitive::<UInt64Type>()
            .values()
            .inner()
            .typed_data::<i64>(),
        t => {
            return Err(ParquetError::General(format!(
                "a {t} column for a 64-bit integer one"
            )));
        }
    };
    Ok(values)
}
