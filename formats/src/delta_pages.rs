//! DELTA_BINARY_PACKED pages of 64-bit integers, as parquet-rs's encoder writes them, for
//! `int_pages`' columns.
//!
//! The tables' integer columns are times, sequence numbers and counts: their deltas are
//! nearly constant, so nearly every miniblock of 64 values packs to nothing. The crate's
//! encoder still takes each value through its bit writer (a call a value, at a width of
//! zero), and its column writer finds each batch's bounds one value at a time, dispatched
//! on the column's type: 4–5 % of the ingest's CPU for its four such columns (session 93,
//! 40-minute runs). Here a block's deltas are taken in one pass, each miniblock's width
//! found by an or of its values above the least delta and packed 64 at a time. With its
//! lists' repetition levels written without a pass over them too (`split_pages`), the
//! ingest's IMU table's thread took 7–12 % fewer profile samples, its odometer table's
//! 10–15 %. The encoding's layout stays the crate's: its blocks of 256 values in four
//! miniblocks, a page's header, how the last block is padded.

use std::borrow::Cow;

use arrow::array::{Array, AsArray};
use arrow::datatypes::{DataType, Int64Type, UInt64Type};
use parquet::basic::{Encoding, Type as PhysicalType};
use parquet::errors::ParquetError;

use crate::int_pages::IntEncoder;
use crate::split_pages::put_uleb128;

/// Values a miniblock (the crate's for 64-bit integers).
const MINIBLOCK: usize = 64;
/// Miniblocks a block.
const MINIBLOCKS: usize = 4;
/// Values a block.
const BLOCK: usize = MINIBLOCK * MINIBLOCKS;

/// A page's encoder: the crate's `DeltaBitPackEncoder` for 64-bit values, state for state.
#[derive(Debug)]
pub(crate) struct DeltaEncoder {
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

impl DeltaEncoder {
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
}

impl Default for DeltaEncoder {
    fn default() -> Self {
        Self {
            total: 0,
            first: 0,
            current: 0,
            deltas: Vec::with_capacity(BLOCK),
            blocks: Vec::new(),
        }
    }
}

impl IntEncoder for DeltaEncoder {
    type Value = i64;
    const PHYSICAL: PhysicalType = PhysicalType::INT64;
    const ENCODING: Encoding = Encoding::DELTA_BINARY_PACKED;

    /// An `Int64` array's values, or a `UInt64` one's bits as i64s (as the Arrow writer
    /// stores them).
    fn values(array: &dyn Array) -> Result<Cow<'_, [i64]>, ParquetError> {
        match array.data_type() {
            DataType::Int64 => Ok(Cow::Borrowed(array.as_primitive::<Int64Type>().values())),
            DataType::UInt64 => Ok(Cow::Borrowed(
                array
                    .as_primitive::<UInt64Type>()
                    .values()
                    .inner()
                    .typed_data::<i64>(),
            )),
            t => Err(ParquetError::General(format!(
                "a {t} column for a 64-bit integer one"
            ))),
        }
    }

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

    /// The blocks encoded so far (the crate's estimate leaves the block being filled out).
    fn estimated_bytes(&self) -> usize {
        self.blocks.len()
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
