//! The column writers of a [`crate::parquet_io::ParquetSink`]'s row group.
//!
//! The Arrow writer's own column writer (`ArrowColumnWriter`) first computes each leaf's
//! levels and the indices of its non-null values (8 bytes a value), then gathers the
//! values by those indices into a copy, and only then encodes them. A column that cannot
//! hold a null has nothing to gather: a required integer or float column, or a required
//! fixed-size list of required 64-bit integers or floats (a 3-vector). Its values go to
//! the same typed column writer as they lie in the array, with the levels such a column
//! always has (none when flat; in a list, every value defined and each list's first value
//! starting a record). Float columns go to [`SplitColumn`] instead, which encodes their
//! pages itself (`split_pages`), and flat integer ones, nullable ones too, to
//! [`IntColumn`] (`int_pages`: 64-bit ones delta-encoded, 32-bit and narrower ones
//! plain). The pages, the column chunk and its metadata are the Arrow writer's, byte for
//! byte (`parquet_io`'s tests compare whole files).

use std::io::Read;
use std::sync::{Arc, Mutex};

use arrow::array::{Array, ArrayRef, AsArray};
use arrow::datatypes::{DataType, Field, Float32Type, Float64Type, Int64Type, UInt64Type};
use bytes::Bytes;
use parquet::arrow::arrow_writer::{ArrowColumnChunk, ArrowColumnWriter};
use parquet::basic::Type as PhysicalType;
use parquet::column::page::{CompressedPage, PageWriteSpec, PageWriter};
use parquet::column::writer::{ColumnCloseResult, ColumnWriter, get_column_writer};
use parquet::errors::ParquetError;
use parquet::file::properties::WriterPropertiesPtr;
use parquet::file::reader::{ChunkReader, Length};
use parquet::file::writer::{SerializedPageWriter, SerializedRowGroupWriter, TrackedWrite};
use parquet::schema::types::ColumnDescPtr;

use crate::delta_pages::DeltaEncoder;
use crate::int_pages::IntColumn;
use crate::plain_pages::PlainEncoder;
use crate::split_pages::SplitColumn;

/// How a column's values lie when it is written directly (see the module's notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DirectShape {
    /// One value a row.
    Flat,
    /// One value a row, or a null: a flat nullable integer column (only `int_pages`
    /// takes it).
    Nullable,
    /// `len` values a row, in a required fixed-size list.
    List { len: usize },
}

/// Whether `field`'s values can go to its column writer directly, and how they lie.
pub(crate) fn direct_shape(field: &Field) -> Option<DirectShape> {
    let plain = |t: &DataType| {
        matches!(
            t,
            DataType::Int64 | DataType::UInt64 | DataType::Float32 | DataType::Float64
        )
    };
    // Stored as INT32 (flat ones only).
    let narrow = |t: &DataType| {
        matches!(
            t,
            DataType::Int8
                | DataType::Int16
                | DataType::Int32
                | DataType::UInt8
                | DataType::UInt16
                | DataType::UInt32
        )
    };
    if field.is_nullable() {
        let t = field.data_type();
        let integer = matches!(t, DataType::Int64 | DataType::UInt64) || narrow(t);
        return integer.then_some(DirectShape::Nullable);
    }
    match field.data_type() {
        t if plain(t) || narrow(t) => Some(DirectShape::Flat),
        DataType::FixedSizeList(item, len)
            if !item.is_nullable() && plain(item.data_type()) && *len > 0 =>
        {
            Some(DirectShape::List {
                len: usize::try_from(*len).ok()?,
            })
        }
        _ => None,
    }
}

/// The writer of one leaf column in a row group.
pub(crate) enum LeafWriter {
    /// The Arrow writer's (any column).
    Arrow(Box<ArrowColumnWriter>),
    /// A column without nulls, written from its values as they lie.
    Direct(Box<DirectColumn>),
}

/// A leaf column's encoded chunk, ready to be appended to its row group.
pub(crate) enum LeafChunk {
    Arrow(ArrowColumnChunk),
    Direct {
        pages: ChunkPages,
        close: ColumnCloseResult,
    },
}

impl LeafWriter {
    /// Encodes what is left of the column and returns its chunk.
    pub(crate) fn close(self) -> Result<LeafChunk, ParquetError> {
        match self {
            LeafWriter::Arrow(w) => (*w).close().map(LeafChunk::Arrow),
            LeafWriter::Direct(w) => (*w).close(),
        }
    }
}

impl LeafChunk {
    /// Appends the chunk to `group` (its next column).
    pub(crate) fn append_to_row_group<W: std::io::Write + Send>(
        self,
        group: &mut SerializedRowGroupWriter<'_, W>,
    ) -> Result<(), ParquetError> {
        match self {
            LeafChunk::Arrow(chunk) => chunk.append_to_row_group(group),
            LeafChunk::Direct { pages, close } => group.append_column(&pages, close),
        }
    }
}

/// A column chunk's pages as the column writer emits them, each in a buffer of its own
/// (a page's header, then its bytes; one growing buffer for the whole chunk would hold up
/// to twice the chunk while it grows), in order.
#[derive(Debug, Default)]
pub(crate) struct ChunkPages {
    pieces: Vec<Bytes>,
    len: u64,
}

/// [`ChunkPages`] shared by the column's page writer and the writer that takes them out
/// on close.
type SharedPages = Arc<Mutex<ChunkPages>>;

/// Writes each page as a file's page writer does (`SerializedPageWriter`: the same header,
/// the same bytes, the same offsets within the chunk), into memory.
struct MemoryPages(SharedPages);

impl PageWriter for MemoryPages {
    fn write_page(&mut self, page: CompressedPage) -> Result<PageWriteSpec, ParquetError> {
        self.0
            .lock()
            .map_err(|_| ParquetError::General("a column's pages were poisoned".into()))?
            .push(page)
    }

    fn close(&mut self) -> Result<(), ParquetError> {
        Ok(())
    }
}

impl ChunkPages {
    /// Appends `page` as a file's page writer writes it (`SerializedPageWriter`: the same
    /// header, the same bytes), at the chunk's end: its spec, offset within the chunk.
    pub(crate) fn push(&mut self, page: CompressedPage) -> Result<PageWriteSpec, ParquetError> {
        // Room for the page and its header (a few dozen bytes: no page statistics).
        let mut sink = TrackedWrite::new(Vec::with_capacity(page.data().len() + 256));
        let mut spec = SerializedPageWriter::new(&mut sink).write_page(page)?;
        let piece = Bytes::from(sink.into_inner()?);
        spec.offset += self.len;
        self.len += piece.len() as u64;
        self.pieces.push(piece);
        Ok(spec)
    }
}

impl Length for ChunkPages {
    fn len(&self) -> u64 {
        self.len
    }
}

impl ChunkReader for ChunkPages {
    type T = PagesReader;

    fn get_read(&self, start: u64) -> Result<PagesReader, ParquetError> {
        let mut skip = start;
        let mut pieces = self.pieces.clone().into_iter();
        let mut current = Bytes::new();
        for piece in pieces.by_ref() {
            let n = piece.len() as u64;
            if skip < n {
                current = piece.slice(usize::try_from(skip).unwrap_or(usize::MAX)..);
                break;
            }
            skip -= n;
        }
        Ok(PagesReader { pieces, current })
    }

    fn get_bytes(&self, start: u64, length: usize) -> Result<Bytes, ParquetError> {
        let mut out = vec![0; length];
        self.get_read(start)?.read_exact(&mut out)?;
        Ok(out.into())
    }
}

/// Reads a [`ChunkPages`] from an offset on, piece after piece.
pub(crate) struct PagesReader {
    pieces: std::vec::IntoIter<Bytes>,
    current: Bytes,
}

impl Read for PagesReader {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        while self.current.is_empty() {
            match self.pieces.next() {
                Some(piece) => self.current = piece,
                None => return Ok(0),
            }
        }
        let n = out.len().min(self.current.len());
        out[..n].copy_from_slice(&self.current[..n]);
        self.current = self.current.slice(n..);
        Ok(n)
    }
}

/// A column without nulls written from its values as they lie (see the module's notes):
/// a float column (flat or lists) by [`SplitColumn`] when the file's settings allow, else
/// by the crate's typed column writer.
pub(crate) enum DirectColumn {
    SplitF64(SplitColumn<f64>),
    SplitF32(SplitColumn<f32>),
    Delta(IntColumn<DeltaEncoder>),
    Plain(IntColumn<PlainEncoder>),
    Typed(Box<TypedColumn>),
}

impl DirectColumn {
    /// A writer of the leaf `descr` with the file's `props`, or `None` when the leaf is not
    /// the plain one `shape` needs (a list's leaf repeated once, a flat one not at all).
    pub(crate) fn new(
        descr: ColumnDescPtr,
        props: WriterPropertiesPtr,
        shape: DirectShape,
    ) -> Option<Self> {
        if let Some(c) = SplitColumn::new(descr.clone(), props.clone(), shape) {
            return Some(Self::SplitF64(c));
        }
        if let Some(c) = SplitColumn::new(descr.clone(), props.clone(), shape) {
            return Some(Self::SplitF32(c));
        }
        if let Some(c) = IntColumn::new(descr.clone(), props.clone(), shape) {
            return Some(Self::Delta(c));
        }
        if let Some(c) = IntColumn::new(descr.clone(), props.clone(), shape) {
            return Some(Self::Plain(c));
        }
        TypedColumn::new(descr, props, shape).map(|c| Self::Typed(Box::new(c)))
    }

    /// Whether the column is written as split float pages.
    #[cfg(test)]
    pub(crate) fn is_split(&self) -> bool {
        matches!(self, Self::SplitF64(_) | Self::SplitF32(_))
    }

    /// Whether the column is written as delta-encoded pages of its own.
    #[cfg(test)]
    pub(crate) fn is_delta(&self) -> bool {
        matches!(self, Self::Delta(_))
    }

    /// Whether the column is written as plain integer pages of its own.
    #[cfg(test)]
    pub(crate) fn is_plain(&self) -> bool {
        matches!(self, Self::Plain(_))
    }

    /// Encodes `column`'s rows.
    pub(crate) fn write(&mut self, column: &ArrayRef) -> Result<(), ParquetError> {
        match self {
            Self::SplitF64(w) => w.write_array(column),
            Self::SplitF32(w) => w.write_array(column),
            Self::Delta(w) => w.write_array(column),
            Self::Plain(w) => w.write_array(column),
            Self::Typed(w) => w.write(column),
        }
    }

    /// Closes the column: its pages and what the row group records of them.
    fn close(self) -> Result<LeafChunk, ParquetError> {
        let (pages, close) = match self {
            Self::SplitF64(w) => w.close()?,
            Self::SplitF32(w) => w.close()?,
            Self::Delta(w) => w.close()?,
            Self::Plain(w) => w.close()?,
            Self::Typed(w) => w.close()?,
        };
        Ok(LeafChunk::Direct { pages, close })
    }
}

/// The values of `column` laid out as `shape` says, without nulls: the column itself
/// (flat), or a fixed-size list's values (`len` a row).
pub(crate) fn plain_values(
    column: &ArrayRef,
    shape: DirectShape,
) -> Result<&dyn Array, ParquetError> {
    let values: &dyn Array = match shape {
        DirectShape::Flat | DirectShape::Nullable => column.as_ref(),
        DirectShape::List { len } => {
            let list = column.as_fixed_size_list_opt().ok_or_else(|| {
                ParquetError::General(format!("a {} for a list column", column.data_type()))
            })?;
            if list.null_count() != 0 || list.values().len() != list.len() * len {
                return Err(ParquetError::General(
                    "a list column with nulls or of another length".into(),
                ));
            }
            list.values().as_ref()
        }
    };
    if values.null_count() != 0 {
        return Err(ParquetError::General(
            "nulls in a column that holds none".into(),
        ));
    }
    Ok(values)
}

/// A column without nulls written by the crate's typed column writer.
pub(crate) struct TypedColumn {
    writer: ColumnWriter<'static>,
    pages: SharedPages,
    shape: DirectShape,
    max_def_level: i16,
    /// A list column's levels for the longest batch so far (its prefix serves shorter
    /// ones).
    def_levels: Vec<i16>,
    rep_levels: Vec<i16>,
}

impl TypedColumn {
    /// A writer of the leaf `descr` with the file's `props`, or `None` when the leaf is not
    /// the plain one `shape` needs (a list's leaf repeated once, a flat one not at all).
    fn new(descr: ColumnDescPtr, props: WriterPropertiesPtr, shape: DirectShape) -> Option<Self> {
        let levels_fit = match shape {
            DirectShape::Flat => descr.max_def_level() == 0 && descr.max_rep_level() == 0,
            DirectShape::List { .. } => descr.max_rep_level() == 1,
            DirectShape::Nullable => false,
        };
        // The physical types of the columns it writes (a narrow integer's INT32 column is
        // `int_pages`' alone, or the Arrow writer's).
        let writes = matches!(
            descr.physical_type(),
            PhysicalType::INT64 | PhysicalType::FLOAT | PhysicalType::DOUBLE
        );
        if !levels_fit || !writes {
            return None;
        }
        let max_def_level = descr.max_def_level();
        let pages: SharedPages = Arc::new(Mutex::new(ChunkPages::default()));
        let writer = get_column_writer(descr, props, Box::new(MemoryPages(pages.clone())));
        Some(Self {
            writer,
            pages,
            shape,
            max_def_level,
            def_levels: Vec::new(),
            rep_levels: Vec::new(),
        })
    }

    /// Encodes `column`'s rows.
    fn write(&mut self, column: &ArrayRef) -> Result<(), ParquetError> {
        let values = plain_values(column, self.shape)?;
        let n = values.len();
        let (def, rep) = match self.shape {
            DirectShape::Flat | DirectShape::Nullable => (None, None),
            DirectShape::List { len } => {
                if self.def_levels.len() < n {
                    self.def_levels = vec![self.max_def_level; n];
                    self.rep_levels = (0..n).map(|k| i16::from(k % len != 0)).collect();
                }
                (Some(&self.def_levels[..n]), Some(&self.rep_levels[..n]))
            }
        };
        let written = match (&mut self.writer, values.data_type()) {
            (ColumnWriter::Int64ColumnWriter(w), DataType::Int64) => {
                w.write_batch(values.as_primitive::<Int64Type>().values(), def, rep)
            }
            // As the Arrow writer stores them: the bits of each u64 as an i64.
            (ColumnWriter::Int64ColumnWriter(w), DataType::UInt64) => w.write_batch(
                values
                    .as_primitive::<UInt64Type>()
                    .values()
                    .inner()
                    .typed_data::<i64>(),
                def,
                rep,
            ),
            (ColumnWriter::FloatColumnWriter(w), DataType::Float32) => {
                w.write_batch(values.as_primitive::<Float32Type>().values(), def, rep)
            }
            (ColumnWriter::DoubleColumnWriter(w), DataType::Float64) => {
                w.write_batch(values.as_primitive::<Float64Type>().values(), def, rep)
            }
            (_, t) => Err(ParquetError::General(format!(
                "a {t} column for another physical type"
            ))),
        }?;
        if written != n {
            return Err(ParquetError::General(format!(
                "{written} values of {n} written"
            )));
        }
        Ok(())
    }

    /// Closes the column: its pages and what the row group records of them.
    fn close(self) -> Result<(ChunkPages, ColumnCloseResult), ParquetError> {
        let Self { writer, pages, .. } = self;
        let close = writer.close()?;
        let pages = Arc::try_unwrap(pages)
            .map_err(|_| ParquetError::General("a column's pages still shared".into()))?
            .into_inner()
            .map_err(|_| ParquetError::General("a column's pages were poisoned".into()))?;
        Ok((pages, close))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pages read back from any offset, across pieces, as one buffer would be.
    #[test]
    fn chunk_pages_read_from_any_offset_across_pieces() {
        let whole: Vec<u8> = (0..50u8).collect();
        let pages = ChunkPages {
            pieces: vec![
                Bytes::copy_from_slice(&whole[..7]),
                Bytes::new(),
                Bytes::copy_from_slice(&whole[7..30]),
                Bytes::copy_from_slice(&whole[30..]),
            ],
            len: 50,
        };
        assert_eq!(Length::len(&pages), 50);
        for start in 0..=50 {
            let mut read = Vec::new();
            pages
                .get_read(start)
                .unwrap()
                .read_to_end(&mut read)
                .unwrap();
            assert_eq!(read, whole[start as usize..], "from {start}");
        }
        assert_eq!(pages.get_bytes(5, 30).unwrap(), whole[5..35]);
        assert!(pages.get_bytes(45, 10).is_err(), "past the end");
    }
}
