//! PLAIN pages of 32-bit integers, as parquet-rs's encoder writes them, for `int_pages`'
//! columns: the tables' status words and codes (`UInt16`, `UInt8`) and point ids
//! (`UInt32`), stored as INT32.
//!
//! The Arrow writer widens a narrow column into a new array, then its column writer finds
//! each batch's bounds and copies each value through its encoder, dispatched on the
//! column's type: 11.7 M instructions for the IMU table's status word and as many for the
//! odometer's source code in a 40-minute ingest (session 94). Here a narrow column's
//! values are widened into one i32 copy (an `Int32` or `UInt32` column's are taken as
//! they lie), its bounds found in one pass over it ([`crate::int_pages`]), and its
//! values copied into the page as little-endian bytes, four each.

use std::borrow::Cow;

use arrow::array::{Array, AsArray};
use arrow::datatypes::{
    DataType, Int8Type, Int16Type, Int32Type, UInt8Type, UInt16Type, UInt32Type,
};
use parquet::basic::{Encoding, Type as PhysicalType};
use parquet::errors::ParquetError;

use crate::int_pages::IntEncoder;

/// A page's encoder: the crate's `PlainEncoder` for INT32, its values' bytes as they come.
#[derive(Debug, Default)]
pub(crate) struct PlainEncoder {
    bytes: Vec<u8>,
}

impl IntEncoder for PlainEncoder {
    type Value = i32;
    const PHYSICAL: PhysicalType = PhysicalType::INT32;
    const ENCODING: Encoding = Encoding::PLAIN;

    /// The values as the Arrow writer stores them: narrow ones widened, a `UInt32`'s bits
    /// as an i32's.
    fn values(array: &dyn Array) -> Result<Cow<'_, [i32]>, ParquetError> {
        fn widened<T: Copy + Into<i32>>(values: &[T]) -> Cow<'static, [i32]> {
            Cow::Owned(values.iter().map(|&v| v.into()).collect())
        }
        Ok(match array.data_type() {
            DataType::Int32 => Cow::Borrowed(array.as_primitive::<Int32Type>().values()),
            DataType::UInt32 => Cow::Borrowed(
                array
                    .as_primitive::<UInt32Type>()
                    .values()
                    .inner()
                    .typed_data::<i32>(),
            ),
            DataType::Int16 => widened(array.as_primitive::<Int16Type>().values()),
            DataType::UInt16 => widened(array.as_primitive::<UInt16Type>().values()),
            DataType::Int8 => widened(array.as_primitive::<Int8Type>().values()),
            DataType::UInt8 => widened(array.as_primitive::<UInt8Type>().values()),
            t => {
                return Err(ParquetError::General(format!(
                    "a {t} column for a 32-bit integer one"
                )));
            }
        })
    }

    fn put(&mut self, values: &[i32]) {
        self.bytes
            .extend(values.iter().flat_map(|v| v.to_le_bytes()));
    }

    fn estimated_bytes(&self) -> usize {
        self.bytes.len()
    }

    fn finish_into(&mut self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.bytes);
        self.bytes.clear();
    }
}
