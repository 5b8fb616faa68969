//! Parquet output (zstd, atomic) and input of whole tables.

use std::ops::Range;
use std::path::Path;

use arrow::array::ArrayRef;
use arrow::array::RecordBatch;
use arrow::datatypes::{DataType, FieldRef, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::arrow_writer::{ArrowRowGroupWriterFactory, compute_leaves};
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::{EnabledStatistics, WriterProperties, WriterPropertiesPtr};
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::{ColumnDescPtr, ColumnPath};
use rayon::prelude::*;

use crate::atomic::{AtomicFile, HashedFileWriter};
use crate::error::{FileError, FormatError, io_in_file};
use crate::parquet_columns::{DirectColumn, DirectShape, LeafChunk, LeafWriter, direct_shape};

/// A Parquet file being written; it appears under its name only on [`ParquetSink::finish`].
///
/// Its columns are encoded and compressed side by side (on rayon's pool) by the column
/// writers `ArrowWriter` itself uses (a column without nulls handed its values as they
/// lie, see the `parquet_columns` module), in the same row groups, so the file is the one
/// `ArrowWriter` writes, byte for byte.
pub struct ParquetSink {
    writer: SerializedFileWriter<HashedFileWriter>,
    factory: ArrowRowGroupWriterFactory,
    schema: SchemaRef,
    /// The table's leaf columns, and how a row group's writers of them are made.
    leaves: Leaves,
    /// The row group being filled.
    groups: Groups,
    /// The trailing fields encoded apart, when asked ([`ParquetSink::deferring_from`]).
    deferred: Option<Deferred>,
    file: AtomicFile,
    rows: usize,
}

/// A table's leaf columns, and how a row group's writers of them are made.
#[derive(Clone)]
struct Leaves {
    /// Each leaf's descriptor.
    descr: Vec<ColumnDescPtr>,
    /// Leaf columns of each of the schema's fields, in order.
    per_field: Vec<usize>,
    /// Each field's shape when its values can go to its one leaf's writer directly.
    direct: Vec<Option<DirectShape>>,
    props: WriterPropertiesPtr,
}

impl Leaves {
    /// The writers of the leaves of `fields` for row group `index`: a direct one for each
    /// field [`direct_shape`] allows, else the Arrow writer's from `factory` (which makes
    /// them for every column at once, each with its own codec, a zstd compressor and
    /// decompressor: asked only when a column needs one).
    fn writers(
        &self,
        fields: Range<usize>,
        index: usize,
        factory: Option<&ArrowRowGroupWriterFactory>,
        dest: &Path,
    ) -> Result<Vec<LeafWriter>, FileError> {
        let first_leaf: usize = self.per_field[..fields.start].iter().sum();
        let direct: Vec<Option<DirectColumn>> = self.per_field[fields.clone()]
            .iter()
            .zip(fields)
            .flat_map(|(&n, field)| std::iter::repeat_n((n, field), n))
            .zip(first_leaf..)
            .map(|((n, field), leaf)| {
                self.direct[field].filter(|_| n == 1).and_then(|s| {
                    DirectColumn::new(self.descr[leaf].clone(), self.props.clone(), s)
                })
            })
            .collect();
        let mut arrow = match factory {
            Some(factory) if direct.iter().any(Option::is_none) => factory
                .create_column_writers(index)
                .map_err(|e| parquet_err(dest, e))?,
            _ => Vec::new(),
        }
        .into_iter()
        .skip(first_leaf);
        direct
            .into_iter()
            .map(|d| match (d, arrow.next()) {
                (Some(d), _) => Ok(LeafWriter::Direct(Box::new(d))),
                (None, Some(w)) => Ok(LeafWriter::Arrow(Box::new(w))),
                (None, None) => Err(parquet_err(
                    dest,
                    FormatError::Invalid("fewer column writers than leaf columns".into()),
                )),
            })
            .collect()
    }
}

/// Leaf columns filled row group by row group (a sink's, or its trailing fields').
struct Groups {
    /// The writers of the row group being filled (none between row groups).
    writers: Vec<LeafWriter>,
    /// Rows in that row group.
    rows: usize,
    /// Rows per row group at most.
    max_rows: usize,
    /// Whether long batches' columns are encoded side by side.
    side_by_side: bool,
    /// Row groups begun.
    begun: usize,
}

/// Row groups whose columns are closed: their chunks (every leaf's, in order) and rows.
type Filled = Vec<(Vec<LeafChunk>, usize)>;

impl Groups {
    fn new(max_rows: usize) -> Self {
        Self {
            writers: Vec::new(),
            rows: 0,
            max_rows: max_rows.max(1),
            side_by_side: true,
            begun: 0,
        }
    }

    /// Encodes `batch` (the columns of `fields`, of `leaves_per_field` leaves each), split
    /// where a row group fills (as `ArrowWriter::write` does); `make(index)` gives row
    /// group `index`'s writers at its first rows. Returns the row groups it filled.
    fn write(
        &mut self,
        batch: &RecordBatch,
        fields: &[FieldRef],
        leaves_per_field: &[usize],
        dest: &Path,
        mut make: impl FnMut(usize) -> Result<Vec<LeafWriter>, FileError>,
    ) -> Result<Filled, FileError> {
        let mut filled = Vec::new();
        let n = batch.num_rows();
        let mut at = 0;
        while at < n {
            if self.writers.is_empty() {
                self.writers = make(self.begun)?;
                self.begun += 1;
            }
            let take = (self.max_rows - self.rows).min(n - at);
            let part = if take == n {
                batch.clone()
            } else {
                batch.slice(at, take)
            };
            let written = encode(
                fields,
                leaves_per_field,
                &part,
                &mut self.writers,
                self.side_by_side,
            );
            written.map_err(|e| parquet_err(dest, e))?;
            self.rows += take;
            at += take;
            if self.rows >= self.max_rows {
                filled.extend(self.close(dest)?);
            }
        }
        Ok(filled)
    }

    /// Closes the row group being filled (its columns' last pages side by side): its
    /// chunks and rows; none between row groups.
    fn close(&mut self, dest: &Path) -> Result<Option<(Vec<LeafChunk>, usize)>, FileError> {
        if self.writers.is_empty() {
            return Ok(None);
        }
        let writers = std::mem::take(&mut self.writers);
        let chunks: Result<Vec<LeafChunk>, _> = if self.side_by_side {
            writers.into_par_iter().map(|w| w.close()).collect()
        } else {
            writers.into_iter().map(|w| w.close()).collect()
        };
        let chunks = chunks.map_err(|e| parquet_err(dest, e))?;
        Ok(Some((chunks, std::mem::take(&mut self.rows))))
    }
}

/// The trailing fields of a [`ParquetSink`] whose columns are encoded apart
/// ([`TrailingColumns`]): the row groups wait for them, their leading columns encoded.
struct Deferred {
    /// The first trailing field.
    field: usize,
    /// Row groups whose leading columns are closed, in order.
    waiting: Filled,
}

/// The trailing fields' columns of a [`ParquetSink`] ([`ParquetSink::deferring_from`]),
/// encoded apart from the others (on another thread, at another time) in the same row
/// groups, and handed to [`ParquetSink::finish_with`].
pub struct TrailingColumns {
    dest: std::path::PathBuf,
    /// The trailing fields, from the table's field `first` on.
    fields: Vec<FieldRef>,
    first: usize,
    leaves: Leaves,
    groups: Groups,
    /// Row groups encoded.
    done: Filled,
}

impl TrailingColumns {
    /// The file's final name.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Encodes the next rows of the trailing fields (a batch of those fields only). The
    /// file is the one whole batches make, byte for byte, when these come in the batches
    /// the leading fields came in.
    pub fn write(&mut self, batch: &RecordBatch) -> Result<(), FileError> {
        if batch.num_columns() != self.fields.len() {
            return Err(parquet_err(
                &self.dest,
                FormatError::Invalid(format!(
                    "a batch of {} trailing columns for {}",
                    batch.num_columns(),
                    self.fields.len()
                )),
            ));
        }
        let (leaves, dest) = (&self.leaves, self.dest.as_path());
        let fields = self.first..self.first + self.fields.len();
        let filled = self.groups.write(
            batch,
            &self.fields,
            &leaves.per_field[fields.clone()],
            dest,
            |index| leaves.writers(fields.clone(), index, None, dest),
        )?;
        self.done.extend(filled);
        Ok(())
    }
}

/// Bytes a table's file is written in at a time (the last write may be shorter).
const FILE_BUFFER_BYTES: usize = 1 << 18;

/// Rows of a batch below which its columns are encoded one after the other: spreading
/// them over threads costs more than it saves.
const PARALLEL_ROWS: usize = 4096;

/// The writer settings of every table, in row groups of at most `rows` rows. Sensor
/// columns are high-cardinality floats: a dictionary never pays off and page statistics
/// are not used by any reader here. Floats (f32 and f64, alone or in fixed-size lists)
/// are byte-stream-split, which zstd compresses better and faster than their plain
/// bytes; 64-bit integers (times, sequence numbers, sample and block indices, pulse
/// counts: all monotone) are delta-encoded, so a regular time column takes a few bytes a
/// page instead of five a row.
fn writer_properties(schema: &Schema, rows: usize) -> Result<WriterProperties, FormatError> {
    let level = ZstdLevel::try_new(1)?;
    let mut builder = WriterProperties::builder()
        .set_compression(Compression::ZSTD(level))
        .set_max_row_group_row_count(Some(rows.max(1)))
        .set_dictionary_enabled(false)
        .set_statistics_enabled(EnabledStatistics::Chunk);
    let encoding_of = |t: &DataType| match t {
        DataType::Float32 | DataType::Float64 => Some(Encoding::BYTE_STREAM_SPLIT),
        DataType::Int64 | DataType::UInt64 => Some(Encoding::DELTA_BINARY_PACKED),
        _ => None,
    };
    for field in schema.fields() {
        let name = field.name().clone();
        let column = match field.data_type() {
            DataType::FixedSizeList(item, _) => encoding_of(item.data_type()).map(|e| {
                let path = vec![name, "list".into(), item.name().clone()];
                (ColumnPath::new(path), e)
            }),
            t => encoding_of(t).map(|e| (ColumnPath::new(vec![name]), e)),
        };
        if let Some((path, encoding)) = column {
            builder = builder.set_column_encoding(path, encoding);
        }
    }
    Ok(builder.build())
}

fn parquet_err(path: &Path, e: impl Into<FormatError>) -> FileError {
    e.into().in_file(path)
}

impl ParquetSink {
    /// Starts a zstd-compressed Parquet file at `dest`, in row groups of 2^20 rows.
    pub fn create(dest: &Path, schema: SchemaRef) -> Result<Self, FileError> {
        Self::create_in_row_groups(dest, schema, 1 << 20)
    }

    /// [`Self::create`] in row groups of at most `rows` rows: the writer holds one row
    /// group's encoded rows at a time.
    pub fn create_in_row_groups(
        dest: &Path,
        schema: SchemaRef,
        rows: usize,
    ) -> Result<Self, FileError> {
        if schema.fields().is_empty() {
            return Err(parquet_err(
                dest,
                FormatError::Invalid("a table without columns".into()),
            ));
        }
        let file = AtomicFile::create(dest)?;
        let props = writer_properties(&schema, rows).map_err(|e| parquet_err(dest, e))?;
        // The Parquet writer writes through an 8-KiB buffer, and copies the column chunks
        // it appends in 8-KiB pieces: this buffer makes them writes of 256 KiB (4.8 MB
        // went into the page cache in 3.4 ms in 8-KiB writes, in 0.8 ms in 1-MiB ones;
        // 256-KiB ones took as long as 1-MiB ones, and a buffer of a MiB is memory the
        // process touches for each file it writes at once: 370 of the 40-minute disupt
        // process's page faults).
        // The file is written front to back, and hashed as it is
        // ([`crate::hashing_writer`]).
        let handle = file.hashed_writer(FILE_BUFFER_BYTES)?;
        // `ArrowWriter` sets the file up (the Parquet schema, the Arrow schema in the
        // footer's metadata); its lower-level parts then take the columns.
        let (writer, factory) = ArrowWriter::try_new(handle, schema.clone(), Some(props))
            .and_then(|w| w.into_serialized_writer())
            .map_err(|e| parquet_err(dest, e))?;
        let descr = writer.schema_descr();
        let mut per_field = vec![0; schema.fields().len()];
        for leaf in 0..descr.num_columns() {
            if let Some(n) = per_field.get_mut(descr.get_column_root_idx(leaf)) {
                *n += 1;
            }
        }
        let leaves = Leaves {
            descr: (0..descr.num_columns()).map(|l| descr.column(l)).collect(),
            direct: schema.fields().iter().map(|f| direct_shape(f)).collect(),
            per_field,
            props: writer.properties().clone(),
        };
        Ok(Self {
            writer,
            factory,
            schema,
            leaves,
            groups: Groups::new(rows),
            deferred: None,
            file,
            rows: 0,
        })
    }

    /// Has the fields from `field` on encoded apart, by the returned [`TrailingColumns`]
    /// (which may run on another thread beside this sink's writes):
    /// [`ParquetSink::write`] then takes batches of the leading fields only, the row
    /// groups are held (their leading columns encoded and compressed) until
    /// [`ParquetSink::finish_with`] is given the trailing ones. The trailing fields must
    /// be of the kinds written directly (required numbers, or fixed-size lists of them).
    pub fn deferring_from(mut self, field: usize) -> Result<(Self, TrailingColumns), FileError> {
        let fields = self.schema.fields().len();
        // A nullable integer's direct writer takes the tables' settings only (any other
        // column has the crate's typed writer to fall back on).
        let direct = |f: usize| {
            self.leaves.direct[f].is_some_and(|s| s != DirectShape::Nullable)
                && self.leaves.per_field[f] == 1
        };
        if field == 0 || field >= fields || !(field..fields).all(direct) {
            return Err(self.invalid(format!(
                "fields {field}.. of {fields} cannot be written after the others"
            )));
        }
        let mut groups = Groups::new(self.groups.max_rows);
        groups.side_by_side = self.groups.side_by_side;
        let trailing = TrailingColumns {
            dest: self.file.dest().to_path_buf(),
            fields: self.schema.fields()[field..].to_vec(),
            first: field,
            leaves: self.leaves.clone(),
            groups,
            done: Vec::new(),
        };
        self.deferred = Some(Deferred {
            field,
            waiting: Vec::new(),
        });
        Ok((self, trailing))
    }

    /// The fields written by [`ParquetSink::write`]: all, or the leading ones when some
    /// are deferred.
    fn leading_fields(&self) -> usize {
        self.deferred
            .as_ref()
            .map_or(self.schema.fields().len(), |d| d.field)
    }

    /// An error naming the file.
    fn invalid(&self, why: String) -> FileError {
        parquet_err(self.file.dest(), FormatError::Invalid(why))
    }

    /// Encodes the columns one after the other on the calling thread (the same file):
    /// for a writer that already runs beside other work, such as the ingest's beside its
    /// MCAP writer thread, where spreading the columns over the pool only contends with
    /// that work.
    pub fn on_this_thread(mut self) -> Self {
        self.groups.side_by_side = false;
        self
    }

    /// Writes one batch, split where a row group fills (as `ArrowWriter::write` does).
    pub fn write(&mut self, batch: &RecordBatch) -> Result<(), FileError> {
        let fields = self.leading_fields();
        if batch.num_columns() != fields {
            return Err(self.invalid(format!(
                "a batch of {} columns for a table of {fields}",
                batch.num_columns(),
            )));
        }
        let (leaves, factory, dest) = (&self.leaves, &self.factory, self.file.dest());
        let filled = self.groups.write(
            batch,
            &self.schema.fields()[..fields],
            &leaves.per_field[..fields],
            dest,
            |index| leaves.writers(0..fields, index, Some(factory), dest),
        )?;
        self.rows += batch.num_rows();
        self.take_filled(filled)
    }

    /// Appends the row groups `filled` to the file; or, while trailing fields wait, has
    /// them wait with them.
    fn take_filled(&mut self, filled: Filled) -> Result<(), FileError> {
        match self.deferred.as_mut() {
            Some(d) => {
                d.waiting.extend(filled);
                Ok(())
            }
            None => filled
                .into_iter()
                .try_for_each(|(chunks, _)| self.append_row_group(chunks)),
        }
    }

    /// Closes the row group being filled and takes it ([`Self::take_filled`]).
    fn flush_row_group(&mut self) -> Result<(), FileError> {
        let filled = self.groups.close(self.file.dest())?;
        self.take_filled(filled.into_iter().collect())
    }

    /// Appends a row group of `chunks`, every leaf's in order.
    fn append_row_group(&mut self, chunks: Vec<LeafChunk>) -> Result<(), FileError> {
        let dest = self.file.dest();
        let mut group = self
            .writer
            .next_row_group()
            .map_err(|e| parquet_err(dest, e))?;
        for chunk in chunks {
            chunk
                .append_to_row_group(&mut group)
                .map_err(|e| parquet_err(dest, e))?;
        }
        group.close().map_err(|e| parquet_err(dest, e))?;
        Ok(())
    }

    /// Leaf columns of the row group being filled that are written directly by a writer
    /// of the `kind` asked (all direct ones: `|_| true`).
    #[cfg(test)]
    fn direct_leaves(&self, kind: fn(&DirectColumn) -> bool) -> usize {
        self.groups
            .writers
            .iter()
            .filter(|c| matches!(c, LeafWriter::Direct(d) if kind(d)))
            .count()
    }

    /// The file's final name.
    pub fn dest(&self) -> &Path {
        self.file.dest()
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Closes the Parquet file and renames it into place.
    pub fn finish(self) -> Result<(), FileError> {
        if self.deferred.is_some() {
            return Err(self.invalid("finished without its trailing columns".into()));
        }
        self.close_file()
    }

    /// [`ParquetSink::finish`] of a sink [`ParquetSink::deferring_from`] made: each row
    /// group of the leading columns with `trailing`'s, which must hold the same rows in
    /// the same groups.
    pub fn finish_with(mut self, mut trailing: TrailingColumns) -> Result<(), FileError> {
        self.flush_row_group()?;
        trailing.done.extend(trailing.groups.close(&trailing.dest)?);
        let Some(deferred) = self.deferred.take() else {
            return Err(self.invalid("trailing columns for a sink without them".into()));
        };
        let rows = |g: &Filled| g.iter().map(|(_, n)| *n).collect::<Vec<_>>();
        let (lead, trail) = (rows(&deferred.waiting), rows(&trailing.done));
        if lead != trail {
            return Err(self.invalid(format!(
                "trailing columns of {} rows in {} row groups for {} rows in {}",
                trail.iter().sum::<usize>(),
                trail.len(),
                lead.iter().sum::<usize>(),
                lead.len()
            )));
        }
        for ((mut chunks, _), (rest, _)) in deferred.waiting.into_iter().zip(trailing.done) {
            chunks.extend(rest);
            self.append_row_group(chunks)?;
        }
        self.close_file()
    }

    /// Writes the last row group and the footer, and renames the file into place (its
    /// hash, taken as it was written, told to the listener:
    /// [`crate::hashing_writer::listen_to_written`]).
    fn close_file(mut self) -> Result<(), FileError> {
        self.flush_row_group()?;
        let buffered = self
            .writer
            .into_inner()
            .map_err(|e| parquet_err(self.file.dest(), e))?;
        self.file.commit_written(buffered)
    }
}

/// Encodes `batch` (the columns of `fields`, of `leaves_per_field` leaves each) into
/// `writers` (theirs, in order), side by side when it is long enough and `side_by_side`.
fn encode(
    fields: &[FieldRef],
    leaves_per_field: &[usize],
    batch: &RecordBatch,
    writers: &mut [LeafWriter],
    side_by_side: bool,
) -> Result<(), parquet::errors::ParquetError> {
    // Each field's writers, taking its leaves (computed in its own task: a column's
    // levels, up to 8 bytes a value, are held while that column is written only).
    let mut each = Vec::with_capacity(fields.len());
    let mut rest = writers;
    for ((field, column), &n) in fields.iter().zip(batch.columns()).zip(leaves_per_field) {
        let (writers, after) = rest.split_at_mut(n.min(rest.len()));
        each.push((field, column, writers));
        rest = after;
    }
    let write = |(field, column, writers): (&FieldRef, &ArrayRef, &mut [LeafWriter])| {
        if let [LeafWriter::Direct(w)] = writers {
            return w.write(column);
        }
        let leaves = compute_leaves(field, column)?;
        if leaves.len() != writers.len() {
            return Err(parquet::errors::ParquetError::General(format!(
                "column {:?}: {} leaf columns for {} writers",
                field.name(),
                leaves.len(),
                writers.len()
            )));
        }
        writers
            .iter_mut()
            .zip(&leaves)
            .try_for_each(|(w, leaf)| match w {
                LeafWriter::Arrow(w) => w.write(leaf),
                LeafWriter::Direct(_) => Err(parquet::errors::ParquetError::General(format!(
                    "column {:?}: a direct writer among leaves",
                    field.name()
                ))),
            })
    };
    if side_by_side && batch.num_rows() >= PARALLEL_ROWS {
        each.into_par_iter().try_for_each(write)
    } else {
        each.into_iter().try_for_each(write)
    }
}

/// Writes one batch as a whole Parquet file, atomically.
pub fn write_batch(dest: &Path, batch: &RecordBatch) -> Result<(), FileError> {
    let mut sink = ParquetSink::create(dest, batch.schema())?;
    sink.write(batch)?;
    sink.finish()
}

/// Reads a Parquet file's schema (with its metadata) only.
pub fn read_schema(path: &Path) -> Result<SchemaRef, FileError> {
    let file = std::fs::File::open(path).map_err(|e| io_in_file(path, e))?;
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| parquet_err(path, e))?;
    Ok(builder.schema().clone())
}

/// At most how many rows a Parquet file's footer may make [`row_capacity_hint`] reserve
/// for each byte of the file. The densest file of a run is `odometer.parquet`: about
/// half a byte a row (its times delta-packed, its distances byte-split and compressed),
/// so a byte a row would leave its columns to grow twice over as they are read.
pub const ROWS_PER_FILE_BYTE_MAX: u64 = 4;

/// How many rows to make room for before reading a Parquet file batch by batch: the
/// row count its footer states, but never more than [`ROWS_PER_FILE_BYTE_MAX`] times the
/// file's length in bytes, so that a footer that lies cannot make a reader reserve more
/// than a bounded multiple of the file's size. It is only a hint: a reader's columns
/// still grow past it if the file has more rows.
pub fn row_capacity_hint(path: &Path) -> Result<usize, FileError> {
    let file = std::fs::File::open(path).map_err(|e| io_in_file(path, e))?;
    let len = file.metadata().map_err(|e| io_in_file(path, e))?.len();
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| parquet_err(path, e))?;
    let rows = u64::try_from(builder.metadata().file_metadata().num_rows()).unwrap_or(0);
    Ok(usize::try_from(rows.min(len.saturating_mul(ROWS_PER_FILE_BYTE_MAX))).unwrap_or(0))
}

/// A reader of a Parquet file's batches (of 65 536 rows), and its schema; only the
/// top-level `columns` named, when given (a name the file lacks is left out), and only
/// the first `limit` rows, when given.
fn batch_reader(
    path: &Path,
    columns: Option<&[&str]>,
    limit: Option<usize>,
) -> Result<(SchemaRef, BatchReader), FileError> {
    let file = std::fs::File::open(path).map_err(|e| io_in_file(path, e))?;
    let mut builder =
        ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| parquet_err(path, e))?;
    let schema = builder.schema().clone();
    if let Some(columns) = columns {
        let mask = parquet::arrow::ProjectionMask::columns(
            builder.parquet_schema(),
            columns.iter().copied(),
        );
        builder = builder.with_projection(mask);
    }
    let mut batch = 1 << 16;
    if let Some(rows) = limit {
        builder = builder.with_limit(rows);
        batch = batch.min(rows.max(1));
    }
    let reader = builder
        .with_batch_size(batch)
        .build()
        .map_err(|e| parquet_err(path, e))?;
    Ok((schema, reader))
}

/// The batches of one Parquet file.
type BatchReader = parquet::arrow::arrow_reader::ParquetRecordBatchReader;

/// [`for_each_batch`] reading only the top-level `columns` named (the others are not
/// decoded). Returns the file's whole schema.
pub fn for_each_batch_of(
    path: &Path,
    columns: &[&str],
    each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    let (schema, reader) = batch_reader(path, Some(columns), None)?;
    feed(path, schema, reader, each)
}

/// [`for_each_batch_of`] over the file's first `rows` rows only: the reader decodes no
/// row past them (a page holding one is decompressed, its later values not decoded).
pub fn for_each_batch_of_first(
    path: &Path,
    columns: &[&str],
    rows: usize,
    each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    if rows == 0 {
        return read_schema(path);
    }
    let (schema, reader) = batch_reader(path, Some(columns), Some(rows))?;
    feed(path, schema, reader, each)
}

/// Hands the batches of `reader` (reading `path`) to `each`; returns `schema`.
fn feed(
    path: &Path,
    schema: SchemaRef,
    reader: BatchReader,
    mut each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    for batch in reader {
        let batch = batch.map_err(|e| parquet_err(path, e))?;
        each(&batch).map_err(|e| e.in_file(path))?;
    }
    Ok(schema)
}

/// Reads a Parquet file batch by batch, handing each to `each`: a whole run's columns
/// are built without the file's batches held beside them. Returns the schema.
pub fn for_each_batch(
    path: &Path,
    each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    let (schema, reader) = batch_reader(path, None, None)?;
    feed(path, schema, reader, each)
}

/// Reads a whole Parquet file: its schema and batches.
pub fn read_batches(path: &Path) -> Result<(SchemaRef, Vec<RecordBatch>), FileError> {
    let (schema, reader) = batch_reader(path, None, None)?;
    let batches = reader
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| parquet_err(path, e))?;
    Ok((schema, batches))
}

/// Reads a whole Parquet file as one batch (tables here are one run: tens of MB at most).
pub fn read_table(path: &Path) -> Result<(SchemaRef, RecordBatch), FileError> {
    let (schema, batches) = read_batches(path)?;
    let batch =
        arrow::compute::concat_batches(&schema, &batches).map_err(|e| parquet_err(path, e))?;
    Ok((schema, batch))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hashing_writer::told::told;
    use arrow::array::Float64Array;
    use arrow::datatypes::{Field, Schema};
    use std::sync::Arc;

    #[test]
    fn the_row_hint_is_the_footers_count_within_a_multiple_of_the_files_size() {
        let dir = tempfile::tempdir().expect("temp dir");
        let schema = Arc::new(Schema::new(vec![Field::new("x", DataType::Float64, false)]));
        let write = |name: &str, values: Vec<f64>| {
            let path = dir.path().join(name);
            let batch =
                RecordBatch::try_new(schema.clone(), vec![Arc::new(Float64Array::from(values))])
                    .expect("batch");
            write_batch(&path, &batch).expect("written");
            path
        };
        // Noisy values: many bytes per row, so the footer's count stands.
        let noisy = write(
            "noisy.parquet",
            (0..5000).map(|k| (k as f64).sin()).collect(),
        );
        assert_eq!(row_capacity_hint(&noisy).expect("hint"), 5000);
        // An odometer's distances (a ramp in whole centimetres): fewer bytes than rows,
        // but within the bound, so the footer's count still stands.
        let ramp = write(
            "ramp.parquet",
            (0..200_000)
                .map(|k| f64::from(k * 13 / 10) * 0.01)
                .collect(),
        );
        let bytes = std::fs::metadata(&ramp).expect("size").len() as usize;
        assert!(bytes < 200_000 && 200_000 <= bytes * ROWS_PER_FILE_BYTE_MAX as usize);
        assert_eq!(row_capacity_hint(&ramp).expect("hint"), 200_000);
        // A constant column compresses to far fewer bytes than rows: the file's size
        // bounds the hint, and reading still gives every row.
        let flat = write("flat.parquet", vec![1.0; 200_000]);
        let bytes = std::fs::metadata(&flat).expect("size").len() as usize;
        assert!(bytes * (ROWS_PER_FILE_BYTE_MAX as usize) < 200_000);
        assert_eq!(
            row_capacity_hint(&flat).expect("hint"),
            bytes * ROWS_PER_FILE_BYTE_MAX as usize
        );
        let mut rows = 0;
        for_each_batch(&flat, |b| {
            rows += b.num_rows();
            Ok(())
        })
        .expect("read");
        assert_eq!(rows, 200_000);
        // A missing file is an error naming it.
        let err = row_capacity_hint(&dir.path().join("none.parquet")).expect_err("missing");
        assert!(err.to_string().contains("none.parquet"), "{err}");
    }

    /// The footer's metadata of the Parquet file at `path`.
    fn file_metadata(path: &Path) -> Arc<parquet::file::metadata::ParquetMetaData> {
        let file = std::fs::File::open(path).expect("file");
        ParquetRecordBatchReaderBuilder::try_new(file)
            .expect("reader")
            .metadata()
            .clone()
    }

    /// Batches of `batch(first row, rows)` of one row, of a block and one either side, of
    /// a write batch and one either side, none, and long ones: blocks, miniblocks and pages
    /// end within a batch, across batches and at a row group's end (in groups of 50 000).
    fn awkward_batches(batch: impl Fn(u64, u64) -> RecordBatch) -> Vec<RecordBatch> {
        let mut batches = Vec::new();
        let mut lo = 0;
        for n in [
            1, 255, 256, 257, 1023, 1024, 1025, 0, 7, 20_000, 30_000, 2, 41_000, 5, 20_480, 333,
        ] {
            batches.push(batch(lo, n));
            lo += n;
        }
        batches
    }

    /// Writes `batches` through a sink in row groups of 50 000 rows, checks that `leaves`
    /// of its columns are written directly by a writer of the `kind` asked, and that the
    /// file is `ArrowWriter`'s byte for byte; returns its metadata.
    fn sink_writes_arrow_writers_file(
        schema: &SchemaRef,
        batches: &[RecordBatch],
        kind: fn(&DirectColumn) -> bool,
        leaves: usize,
    ) -> Arc<parquet::file::metadata::ParquetMetaData> {
        let group_rows = 50_000;
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("table.parquet");
        let mut sink =
            ParquetSink::create_in_row_groups(&path, schema.clone(), group_rows).expect("sink");
        for b in batches {
            sink.write(b).expect("written");
        }
        assert_eq!(sink.direct_leaves(kind), leaves, "columns written directly");
        sink.finish().expect("finished");
        let plain = arrow_writer_bytes(schema, group_rows, batches);
        assert!(std::fs::read(&path).expect("read") == plain, "differs");
        file_metadata(&path)
    }

    /// The file `ArrowWriter` writes of `batches` with the sink's settings, in row groups
    /// of at most `rows` rows.
    fn arrow_writer_bytes(schema: &SchemaRef, rows: usize, batches: &[RecordBatch]) -> Vec<u8> {
        let mut plain = Vec::new();
        let props = writer_properties(schema, rows).expect("settings");
        let mut writer =
            ArrowWriter::try_new(&mut plain, schema.clone(), Some(props)).expect("arrow writer");
        for b in batches {
            writer.write(b).expect("written");
        }
        writer.close().expect("closed");
        plain
    }

    /// Rows per row group of the tests' sinks.
    const GROUP_ROWS: usize = 10_000;

    /// Batches of `batch(first row, rows)` in [`GROUP_ROWS`]' groups: 7000 + 3000 fill
    /// the first group exactly, 25 000 splits across three, then short batches and an
    /// empty one. Returns them and their rows.
    fn batches_of(batch: impl Fn(usize, usize) -> RecordBatch) -> (Vec<RecordBatch>, usize) {
        let mut batches = Vec::new();
        let mut lo = 0;
        for n in [7000, 3000, 25_000, 100, 0, 4999] {
            batches.push(batch(lo, n));
            lo += n;
        }
        (batches, lo)
    }

    /// The sink's columns, encoded side by side (or on the calling thread) and split into
    /// row groups by the sink, make the file `ArrowWriter` makes with the same settings,
    /// byte for byte: batches
    /// long and short (either side of [`PARALLEL_ROWS`]), row groups filled exactly and
    /// split mid-batch, an empty batch; columns written directly (i64, u64 past i64's
    /// range, f64, f32, a 3-vector of f64 and a pair of f32) beside the Arrow writer's
    /// (nullable i64 and f64, booleans, strings).
    #[test]
    fn the_sink_writes_what_arrow_writer_writes_byte_for_byte() {
        use arrow::array::{ArrayRef, Int64Array};
        use arrow::array::{BooleanArray, Float32Array, StringArray};
        use arrow::array::{UInt64Array, builder::Float32Builder};
        let pair_item = Arc::new(Field::new("item", DataType::Float32, false));
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("x", DataType::Float64, false),
            Field::new("v", crate::schema::vec3_type(), false),
            Field::new("maybe", DataType::Int64, true),
            Field::new("h", DataType::Float32, false),
            Field::new("count", DataType::UInt64, false),
            Field::new("pair", DataType::FixedSizeList(pair_item.clone(), 2), false),
            Field::new("ok", DataType::Boolean, false),
            Field::new("name", DataType::Utf8, false),
            Field::new("maybe_x", DataType::Float64, true),
        ]));
        let batch = |lo: usize, n: usize| {
            let x: Vec<f64> = (lo..lo + n).map(|k| (k as f64 * 0.37).sin()).collect();
            let v: Vec<[f64; 3]> = x.iter().map(|&x| [x, -2.0 * x, x * x]).collect();
            let columns: Vec<ArrayRef> = vec![
                Arc::new(Int64Array::from_iter_values(
                    (lo..lo + n).map(|k| k as i64 * 10_000_000),
                )),
                Arc::new(Float64Array::from(x.clone())),
                crate::tables::vec3_to_array(&v),
                Arc::new(Int64Array::from_iter(
                    (lo..lo + n).map(|k| (k % 3 != 0).then_some(k as i64)),
                )),
                Arc::new(Float32Array::from_iter_values(x.iter().map(|&x| x as f32))),
                // Past i64::MAX too: stored as the u64's bits.
                Arc::new(UInt64Array::from_iter_values(
                    (lo..lo + n).map(|k| u64::MAX - 7 * k as u64),
                )),
                {
                    let mut pairs =
                        arrow::array::FixedSizeListBuilder::new(Float32Builder::new(), 2)
                            .with_field(pair_item.clone());
                    for &x in &x {
                        pairs.values().append_slice(&[x as f32, -(x as f32)]);
                        pairs.append(true);
                    }
                    Arc::new(pairs.finish()) as ArrayRef
                },
                Arc::new(BooleanArray::from_iter(
                    (lo..lo + n).map(|k| Some(k % 5 == 0)),
                )),
                Arc::new(StringArray::from_iter_values(
                    (lo..lo + n).map(|k| format!("r{}", k % 11)),
                )),
                Arc::new(Float64Array::from_iter(
                    x.iter().map(|&x| (x > 0.0).then_some(x)),
                )),
            ];
            RecordBatch::try_new(schema.clone(), columns).expect("batch")
        };
        let group_rows = GROUP_ROWS;
        let (batches, lo) = batches_of(batch);
        let dir = tempfile::tempdir().expect("temp dir");
        let write = |name: &str, side_by_side: bool| {
            let path = dir.path().join(name);
            let mut sink =
                ParquetSink::create_in_row_groups(&path, schema.clone(), group_rows).expect("sink");
            if !side_by_side {
                sink = sink.on_this_thread();
            }
            for (i, b) in batches.iter().enumerate() {
                sink.write(b).expect("written");
                if i == 0 {
                    // The plain columns without nulls are written directly: t_ns, x, v, h,
                    // count, pair; the floats x, v, h and pair as split pages; and the
                    // nullable integer maybe as delta-encoded pages.
                    assert_eq!(sink.direct_leaves(|_| true), 7);
                    assert_eq!(sink.direct_leaves(DirectColumn::is_split), 4);
                }
            }
            assert_eq!(sink.rows(), lo);
            sink.finish().expect("finished");
            path
        };
        let path = write("sink.parquet", true);
        let one_thread = write("one_thread.parquet", false);

        let plain = arrow_writer_bytes(&schema, group_rows, &batches);

        for p in [&path, &one_thread] {
            let ours = std::fs::read(p).expect("read");
            assert_eq!(ours.len(), plain.len());
            assert!(ours == plain, "{} differs", p.display());
        }
        let meta = file_metadata(&path);
        let groups: Vec<i64> = meta.row_groups().iter().map(|g| g.num_rows()).collect();
        assert_eq!(groups, [10_000, 10_000, 10_000, 10_000, 99]);
        // A batch of another shape is refused, naming the file; so is a table without
        // columns.
        let mut sink =
            ParquetSink::create(&dir.path().join("odd.parquet"), schema.clone()).expect("sink");
        let err = sink
            .write(&batches[0].project(&[0, 1]).expect("two columns"))
            .expect_err("two columns of four")
            .to_string();
        assert!(
            err.contains("odd.parquet") && err.contains("2 columns"),
            "{err}"
        );
        let empty = Arc::new(Schema::empty());
        assert!(ParquetSink::create(&dir.path().join("none.parquet"), empty).is_err());
    }

    /// Only a file's first rows are handed over, in order, whatever their count: none,
    /// within the first batch, across batches, past the end.
    #[test]
    fn the_first_rows_are_read_and_no_more() {
        use arrow::array::Int64Array;
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("x", DataType::Float64, false),
        ]));
        let n = 150_000;
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![
                Arc::new(Int64Array::from_iter_values(0..n as i64)),
                Arc::new(Float64Array::from_iter_values(
                    (0..n).map(|k| k as f64 * 0.5),
                )),
            ],
        )
        .expect("batch");
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("first.parquet");
        write_batch(&path, &batch).expect("written");
        for rows in [0, 1, 3_000, 65_536, 70_001, n, n + 10] {
            let mut got = Vec::new();
            let schema_read = for_each_batch_of_first(&path, &["x"], rows, |b| {
                got.extend(crate::tables::f64_column(b, "x")?);
                Ok(())
            })
            .expect("read");
            assert_eq!(schema_read.fields().len(), 2, "the whole schema");
            let want: Vec<f64> = (0..rows.min(n)).map(|k| k as f64 * 0.5).collect();
            assert_eq!(got, want, "{rows} rows");
        }
        let err = for_each_batch_of_first(&dir.path().join("none.parquet"), &["x"], 5, |_| Ok(()))
            .expect_err("missing");
        assert!(err.to_string().contains("none.parquet"), "{err}");
    }

    /// A row group whose columns take several pages each (a page holds about 1 MB) is
    /// the one `ArrowWriter` writes, byte for byte.
    #[test]
    fn columns_of_several_pages_are_written_as_arrow_writer_writes_them() {
        use arrow::array::{ArrayRef, Float32Array, Int64Array};
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("x", DataType::Float64, false),
            Field::new("v", crate::schema::vec3_type(), false),
            Field::new("h", DataType::Float32, false),
        ]));
        let n = 400_000;
        let x: Vec<f64> = (0..n).map(|k| (k as f64 * 0.013).sin() * 1e3).collect();
        let v: Vec<[f64; 3]> = x.iter().map(|&x| [x, x.cos(), -x]).collect();
        let columns: Vec<ArrayRef> = vec![
            Arc::new(Int64Array::from_iter_values((0..n).map(|k| k as i64 * 7))),
            Arc::new(Float64Array::from(x.clone())),
            crate::tables::vec3_to_array(&v),
            Arc::new(Float32Array::from_iter_values(x.iter().map(|&x| x as f32))),
        ];
        let batch = RecordBatch::try_new(schema.clone(), columns).expect("batch");
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("pages.parquet");
        let mut sink = ParquetSink::create(&path, schema.clone()).expect("sink");
        sink.write(&batch).expect("written");
        sink.finish().expect("finished");
        let plain = arrow_writer_bytes(&schema, 1 << 20, std::slice::from_ref(&batch));
        let meta = file_metadata(&path);
        let x_chunk = meta.row_group(0).column(1);
        assert!(
            x_chunk.compressed_size() > 1 << 20,
            "x's chunk spans pages: {} bytes",
            x_chunk.compressed_size()
        );
        assert!(std::fs::read(&path).expect("read") == plain, "differs");
    }

    /// Trailing fields encoded apart ([`ParquetSink::deferring_from`], on another thread
    /// beside the leading ones) make the file whole batches make, byte for byte, when
    /// they come in the same batches (row groups filled exactly, split mid-batch, an empty
    /// batch; a leading field the Arrow writer writes); in other batches, the same table.
    /// Misuse is an error naming the file: trailing rows missing or too many, a trailing
    /// field that is not written directly, finishing without them or with them unasked.
    #[test]
    fn trailing_fields_encoded_apart_make_the_same_file() {
        use arrow::array::{ArrayRef, Float32Array, Int64Array, UInt64Array};
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("maybe", DataType::Int64, true),
            Field::new("v", crate::schema::vec3_type(), false),
            Field::new("h", DataType::Float32, false),
            Field::new("count", DataType::UInt64, false),
        ]));
        let lead = 2;
        let batch = |lo: usize, n: usize| {
            let x: Vec<f64> = (lo..lo + n).map(|k| (k as f64 * 0.37).sin()).collect();
            let v: Vec<[f64; 3]> = x.iter().map(|&x| [x, -2.0 * x, x * x]).collect();
            let columns: Vec<ArrayRef> = vec![
                Arc::new(Int64Array::from_iter_values((lo..lo + n).map(|k| k as i64))),
                Arc::new(Int64Array::from_iter(
                    (lo..lo + n).map(|k| (k % 3 != 0).then_some(k as i64)),
                )),
                crate::tables::vec3_to_array(&v),
                Arc::new(Float32Array::from_iter_values(x.iter().map(|&x| x as f32))),
                Arc::new(UInt64Array::from_iter_values(
                    (lo..lo + n).map(|k| 3 * k as u64),
                )),
            ];
            RecordBatch::try_new(schema.clone(), columns).expect("batch")
        };
        let group_rows = GROUP_ROWS;
        let (batches, lo) = batches_of(batch);
        let leading: Vec<usize> = (0..lead).collect();
        let trailing: Vec<usize> = (lead..schema.fields().len()).collect();
        let dir = tempfile::tempdir().expect("temp dir");
        let deferred_sink = |name: &str| {
            ParquetSink::create_in_row_groups(&dir.path().join(name), schema.clone(), group_rows)
                .expect("sink")
                .deferring_from(lead)
                .expect("deferring")
        };
        let (mut sink, mut rest) = deferred_sink("deferred.parquet");
        assert_eq!(told(&dir.path().join("deferred.parquet")), None);
        rayon::join(
            || {
                for b in &batches {
                    sink.write(&b.project(&leading).expect("leading"))
                        .expect("written");
                }
            },
            || {
                for b in &batches {
                    rest.write(&b.project(&trailing).expect("trailing"))
                        .expect("written");
                }
            },
        );
        sink.finish_with(rest).expect("finished");
        let ours = std::fs::read(dir.path().join("deferred.parquet")).expect("read");
        assert!(ours == arrow_writer_bytes(&schema, group_rows, &batches));
        // Hashed as it was written, and told once in place.
        assert_eq!(
            told(&dir.path().join("deferred.parquet")),
            Some(blake3::hash(&ours))
        );

        // The trailing rows in other batches: the same table.
        let whole = arrow::compute::concat_batches(&schema, &batches).expect("whole");
        let (mut sink, mut rest) = deferred_sink("other_batches.parquet");
        let trailing_rows = whole.project(&trailing).expect("trailing");
        rest.write(&trailing_rows.slice(0, 12_345))
            .expect("written");
        for b in &batches {
            sink.write(&b.project(&leading).expect("leading"))
                .expect("written");
        }
        rest.write(&trailing_rows.slice(12_345, lo - 12_345))
            .expect("written");
        sink.finish_with(rest).expect("finished");
        let (_, back) = read_table(&dir.path().join("other_batches.parquet")).expect("read");
        assert_eq!(back, whole);

        // Misuse.
        let (mut sink, mut rest) = deferred_sink("missing.parquet");
        sink.write(&batches[0].project(&leading).expect("leading"))
            .expect("written");
        rest.write(&trailing_rows.slice(0, 10)).expect("written");
        let err = sink
            .finish_with(rest)
            .expect_err("rows missing")
            .to_string();
        assert!(
            err.contains("missing.parquet")
                && err.contains("of 10 rows in 1 row groups for 7000 rows in 1"),
            "{err}"
        );
        assert!(!dir.path().join("missing.parquet").exists());
        let (mut sink, mut rest) = deferred_sink("too_many.parquet");
        sink.write(&batches[0].project(&leading).expect("leading"))
            .expect("written");
        rest.write(&trailing_rows.slice(0, 10_001))
            .expect("written");
        let err = sink.finish_with(rest).expect_err("too many").to_string();
        assert!(err.contains("10001 rows in 2 row groups for 7000"), "{err}");
        let (sink, _) = deferred_sink("unfinished.parquet");
        let err = sink.finish().expect_err("no trailing").to_string();
        assert!(err.contains("without its trailing columns"), "{err}");
        let err = ParquetSink::create(&dir.path().join("odd.parquet"), schema.clone())
            .expect("sink")
            .deferring_from(1)
            .err()
            .expect("a nullable trailing field")
            .to_string();
        assert!(err.contains("fields 1.. of 5"), "{err}");
        let (_, rest) = deferred_sink("other.parquet");
        let plain =
            ParquetSink::create(&dir.path().join("plain.parquet"), schema.clone()).expect("sink");
        let err = plain.finish_with(rest).expect_err("unasked").to_string();
        assert!(
            err.contains("plain.parquet") && err.contains("without them"),
            "{err}"
        );
    }

    /// A required fixed-size list of `len` required values of `item`.
    fn list_of(item: DataType, len: i32) -> Field {
        let item = Arc::new(Field::new("item", item, false));
        Field::new(
            format!("list{len}"),
            DataType::FixedSizeList(item, len),
            false,
        )
    }

    /// [`list_of`]'s column of `values`, `len` a row.
    fn list_column<T: arrow::datatypes::ArrowPrimitiveType>(
        len: i32,
        values: impl Iterator<Item = T::Native>,
    ) -> ArrayRef {
        let values = arrow::array::PrimitiveArray::<T>::from_iter_values(values);
        let item = Arc::new(Field::new("item", T::DATA_TYPE, false));
        Arc::new(arrow::array::FixedSizeListArray::new(
            item,
            len,
            Arc::new(values),
            None,
        ))
    }

    /// Float columns written as split pages make `ArrowWriter`'s file byte for byte
    /// whatever their values and however they come: NaNs first, in runs and alone, a
    /// column of NaNs only (no bounds), zeros of both signs at either bound, infinities,
    /// subnormals; batches of one value, of a write batch and one either side, and long
    /// ones (one of exactly a page's rows), so pages are cut within a batch, across
    /// batches, at a row group's end; flat, and in lists of 1 (repetition levels all 0),
    /// 9 and 17 values (runs of equal levels, pages cut by their bytes).
    #[test]
    fn split_float_pages_are_arrow_writers_whatever_the_values_and_batches() {
        use arrow::array::Float32Array;
        use arrow::datatypes::{Float32Type, Float64Type};
        let schema = Arc::new(Schema::new(vec![
            Field::new("x", DataType::Float64, false),
            Field::new("h", DataType::Float32, false),
            Field::new("nan", DataType::Float32, false),
            Field::new("zero", DataType::Float64, false),
            list_of(DataType::Float64, 1),
            list_of(DataType::Float32, 9),
            list_of(DataType::Float64, 17),
        ]));
        let x_of = |k: usize| match k % 9973 {
            0..=2 => f64::NAN,
            100 => f64::INFINITY,
            101 => -f64::MIN_POSITIVE / 4.0,
            _ => ((k as f64) * 0.011).sin() * 1e4,
        };
        let zero_of = |k: usize| match k % 3 {
            0 => 0.0,
            1 => -0.0,
            _ => -((k % 5) as f64),
        };
        let batch = |lo: usize, n: usize| {
            let rows = lo..lo + n;
            let columns: Vec<ArrayRef> = vec![
                Arc::new(Float64Array::from_iter_values(rows.clone().map(x_of))),
                Arc::new(Float32Array::from_iter_values(
                    rows.clone().map(|k| x_of(k + 7) as f32),
                )),
                Arc::new(Float32Array::from_iter_values(
                    rows.clone().map(|_| f32::NAN),
                )),
                Arc::new(Float64Array::from_iter_values(rows.clone().map(zero_of))),
                list_column::<Float64Type>(1, rows.clone().flat_map(|k| [x_of(k)])),
                list_column::<Float32Type>(
                    9,
                    rows.clone()
                        .flat_map(|k| (0..9).map(move |j| x_of(k * 9 + j) as f32)),
                ),
                list_column::<Float64Type>(
                    17,
                    rows.flat_map(|k| (0..17).map(move |j| zero_of(k + j))),
                ),
            ];
            RecordBatch::try_new(schema.clone(), columns).expect("batch")
        };
        let mut batches = Vec::new();
        let mut lo = 0;
        for n in [
            20_000, 1, 1023, 1024, 1025, 0, 7, 30_000, 2, 41_000, 5, 20_480, 333,
        ] {
            batches.push(batch(lo, n));
            lo += n;
        }
        let group_rows = 50_000;
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("split.parquet");
        let mut sink =
            ParquetSink::create_in_row_groups(&path, schema.clone(), group_rows).expect("sink");
        for b in &batches {
            sink.write(b).expect("written");
        }
        assert_eq!(sink.direct_leaves(DirectColumn::is_split), 7);
        sink.finish().expect("finished");
        let plain = arrow_writer_bytes(&schema, group_rows, &batches);
        assert!(std::fs::read(&path).expect("read") == plain, "differs");
        // What the file states: x's bounds leave its NaNs out, the NaN column has none,
        // and the zeros' column's maximum is +0.
        let meta = file_metadata(&path);
        let stats = |c: usize| meta.row_group(0).column(c).statistics().cloned();
        match stats(0) {
            Some(parquet::file::statistics::Statistics::Double(s)) => {
                assert_eq!(s.max_opt(), Some(&f64::INFINITY));
                assert!(s.min_opt().is_some_and(|m| m.is_finite()));
            }
            other => panic!("x's statistics: {other:?}"),
        }
        match stats(2) {
            Some(parquet::file::statistics::Statistics::Float(s)) => {
                assert_eq!((s.min_opt(), s.max_opt()), (None, None));
            }
            other => panic!("nan's statistics: {other:?}"),
        }
        match stats(3) {
            Some(parquet::file::statistics::Statistics::Double(s)) => {
                assert_eq!(s.max_opt().map(|m| m.to_bits()), Some(0.0f64.to_bits()));
                assert_eq!(s.min_opt(), Some(&-4.0));
            }
            other => panic!("zero's statistics: {other:?}"),
        }
    }

    /// 64-bit integer columns written as delta-encoded pages of their own make
    /// `ArrowWriter`'s file byte for byte whatever their values and however they come:
    /// regular times, a constant, counts stepping back and forth, values spread over all
    /// 64 bits (every miniblock width), the extremes wrapping their deltas around, u64s
    /// past i64's range (bounds in unsigned order), signed ones below zero; batches of
    /// one value, of a block and one either side, of a write batch and one either side,
    /// none, and long ones, so blocks, miniblocks and pages end within a batch, across
    /// batches and at a row group's end. Nullable columns too: a null every fifth row,
    /// none (with and without a validity buffer), runs of nulls longer than a write
    /// batch and than a page (all-null batches, pages and row groups' stretches), u64s
    /// with nulls.
    #[test]
    fn delta_integer_pages_are_arrow_writers_whatever_the_values_and_batches() {
        use arrow::array::{Int64Array, UInt64Array};
        use arrow::buffer::{BooleanBuffer, NullBuffer};
        // Sequence numbers crossing i64's greatest value in the first row group.
        const SEQ_BASE: u64 = (1 << 63) - 20_000;
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("seq", DataType::UInt64, false),
            Field::new("constant", DataType::Int64, false),
            Field::new("back_and_forth", DataType::Int64, false),
            Field::new("spread", DataType::Int64, false),
            Field::new("spread_u", DataType::UInt64, false),
            Field::new("extremes", DataType::Int64, false),
            Field::new("nullable", DataType::Int64, true),
            Field::new("never_null", DataType::Int64, true),
            Field::new("valid_buffer", DataType::Int64, true),
            Field::new("null_runs", DataType::Int64, true),
            Field::new("nullable_u", DataType::UInt64, true),
        ]));
        // A reproducible spread of 64-bit values, of every width in turn.
        let spread = |k: u64| {
            let x = k
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left((k % 61) as u32);
            x >> (k % 64)
        };
        let extremes = |k: u64| match k % 7 {
            0 => i64::MIN,
            1 => i64::MAX,
            2 => 0,
            3 => -1,
            _ => spread(k) as i64,
        };
        let batch = |lo: u64, n: u64| {
            let rows = lo..lo + n;
            let columns: Vec<ArrayRef> = vec![
                Arc::new(Int64Array::from_iter_values(rows.clone().map(|k| {
                    1_700_000_000_000_000_000 + 10_000_000 * k as i64 + (k % 3) as i64
                }))),
                Arc::new(UInt64Array::from_iter_values(
                    rows.clone().map(|k| SEQ_BASE + k),
                )),
                Arc::new(Int64Array::from_iter_values(rows.clone().map(|_| -42))),
                Arc::new(Int64Array::from_iter_values(
                    rows.clone()
                        .map(|k| (k as i64 % 11) * -3 + (k / 500) as i64),
                )),
                Arc::new(Int64Array::from_iter_values(
                    rows.clone().map(|k| spread(k) as i64),
                )),
                Arc::new(UInt64Array::from_iter_values(rows.clone().map(spread))),
                Arc::new(Int64Array::from_iter_values(rows.clone().map(extremes))),
                Arc::new(Int64Array::from_iter(
                    rows.clone().map(|k| (k % 5 != 0).then_some(k as i64)),
                )),
                Arc::new(Int64Array::from_iter_values(
                    rows.clone().map(|k| 7 * k as i64 - 3),
                )),
                Arc::new(Int64Array::new(
                    rows.clone().map(|k| spread(k) as i64).collect(),
                    Some(NullBuffer::new(BooleanBuffer::new_set(n as usize))),
                )),
                Arc::new(Int64Array::from_iter(
                    rows.clone()
                        .map(|k| ((k / 3_000) % 3 != 1).then_some(spread(k) as i64)),
                )),
                Arc::new(UInt64Array::from_iter(
                    rows.map(|k| (k % 7 != 3).then_some(SEQ_BASE + k)),
                )),
            ];
            RecordBatch::try_new(schema.clone(), columns).expect("batch")
        };
        let batches = awkward_batches(batch);
        let meta = sink_writes_arrow_writers_file(&schema, &batches, DirectColumn::is_delta, 12);
        // The unsigned column's bounds are in unsigned order, past i64's range.
        match meta.row_group(0).column(1).statistics() {
            Some(parquet::file::statistics::Statistics::Int64(s)) => {
                assert_eq!(s.min_opt().map(|&m| m as u64), Some(SEQ_BASE));
                assert_eq!(s.max_opt().map(|&m| m as u64), Some(SEQ_BASE + 49_999));
            }
            other => panic!("seq's statistics: {other:?}"),
        }
    }

    /// Integer columns stored as INT32 written as plain pages of their own make
    /// `ArrowWriter`'s file byte for byte: u8, u16 and i8, i16 widened, i32s below zero,
    /// u32s past i32's range (bounds in unsigned order); nullable ones with a null every
    /// fifth row, runs of nulls longer than a page, none; in the delta test's batches.
    #[test]
    fn plain_integer_pages_are_arrow_writers_whatever_the_values_and_batches() {
        use arrow::array::{
            Int8Array, Int16Array, Int32Array, UInt8Array, UInt16Array, UInt32Array,
        };
        let schema = Arc::new(Schema::new(vec![
            Field::new("status", DataType::UInt16, false),
            Field::new("code", DataType::UInt8, false),
            Field::new("id", DataType::UInt32, false),
            Field::new("signed", DataType::Int32, false),
            Field::new("tiny", DataType::Int8, false),
            Field::new("short", DataType::Int16, false),
            Field::new("maybe_code", DataType::UInt8, true),
            Field::new("maybe_id", DataType::UInt32, true),
            Field::new("never_null", DataType::UInt16, true),
        ]));
        let batch = |lo: u64, n: u64| {
            let rows = lo..lo + n;
            let columns: Vec<ArrayRef> = vec![
                Arc::new(UInt16Array::from_iter_values(
                    rows.clone()
                        .map(|k| if k % 7 == 0 { 0x8002 } else { (k % 3) as u16 }),
                )),
                Arc::new(UInt8Array::from_iter_values(
                    rows.clone().map(|k| (k % 4) as u8),
                )),
                Arc::new(UInt32Array::from_iter_values(
                    rows.clone().map(|k| 0x7FFF_FFF0_u32.wrapping_add(k as u32)),
                )),
                Arc::new(Int32Array::from_iter_values(
                    rows.clone().map(|k| (k % 1000) as i32 - 500),
                )),
                Arc::new(Int8Array::from_iter_values(rows.clone().map(|k| k as i8))),
                Arc::new(Int16Array::from_iter_values(
                    rows.clone().map(|k| (k * 37) as i16),
                )),
                Arc::new(UInt8Array::from_iter(
                    rows.clone()
                        .map(|k| (k % 5 != 0).then_some((k % 200) as u8)),
                )),
                Arc::new(UInt32Array::from_iter(
                    rows.clone()
                        .map(|k| ((k / 25_000) % 3 != 1).then_some(u32::MAX - k as u32)),
                )),
                Arc::new(UInt16Array::from_iter_values(rows.map(|k| k as u16))),
            ];
            RecordBatch::try_new(schema.clone(), columns).expect("batch")
        };
        let batches = awkward_batches(batch);
        let meta = sink_writes_arrow_writers_file(&schema, &batches, DirectColumn::is_plain, 9);
        // The unsigned column's bounds are in unsigned order, past i32's range.
        match meta.row_group(0).column(2).statistics() {
            Some(parquet::file::statistics::Statistics::Int32(s)) => {
                assert_eq!(s.min_opt().map(|&m| m as u32), Some(0x7FFF_FFF0));
                assert_eq!(s.max_opt().map(|&m| m as u32), Some(0x7FFF_FFF0 + 49_999));
            }
            other => panic!("id's statistics: {other:?}"),
        }
    }

    /// Floats (f32, f64, in lists too) are byte-stream-split and 64-bit integers
    /// delta-encoded (nullable ones as well), every other column plain; the values read
    /// back are the ones written, bit for bit (NaN, infinities, signed zeros, extremes);
    /// and a regular time column costs almost nothing.
    #[test]
    fn floats_are_split_and_wide_integers_delta_encoded_and_read_back_bit_for_bit() {
        use arrow::array::{
            Array, FixedSizeListArray, Float32Array, Int64Array, UInt16Array, UInt64Array,
        };
        let n = 50_000usize;
        let f32_item = Arc::new(Field::new("item", DataType::Float32, false));
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("seq", DataType::UInt64, false),
            Field::new("pulses", DataType::Int64, true),
            Field::new("x", DataType::Float64, false),
            Field::new("h_m", DataType::Float32, false),
            Field::new("v", DataType::FixedSizeList(f32_item.clone(), 3), false),
            Field::new("status", DataType::UInt16, false),
        ]));
        let specials = [f32::NAN, f32::INFINITY, -0.0, f32::MIN_POSITIVE, f32::MAX];
        let h: Vec<f32> = (0..n)
            .map(|k| {
                specials
                    .get(k)
                    .copied()
                    .unwrap_or((k as f32 * 0.1).sin() * 300.0)
            })
            .collect();
        let v: Vec<f32> = (0..3 * n).map(|k| (k as f32).cos()).collect();
        let columns: Vec<ArrayRef> = vec![
            Arc::new(Int64Array::from_iter_values(
                (0..n as i64).map(|k| 1_700_000_000_000_000_000 + k * 10_000_000),
            )),
            Arc::new(UInt64Array::from_iter_values(
                (0..n as u64).map(|k| k + u64::MAX / 2),
            )),
            Arc::new(Int64Array::from_iter((0..n as i64).map(|k| {
                (k % 7 != 3).then_some(if k == 5 { i64::MIN } else { k / 3 })
            }))),
            Arc::new(Float64Array::from_iter_values((0..n).map(|k| {
                if k == 1 {
                    f64::NEG_INFINITY
                } else {
                    (k as f64).sqrt()
                }
            }))),
            Arc::new(Float32Array::from(h)),
            Arc::new(FixedSizeListArray::new(
                f32_item,
                3,
                Arc::new(Float32Array::from(v)),
                None,
            )),
            Arc::new(UInt16Array::from_iter_values(
                (0..n).map(|k| (k % 5) as u16),
            )),
        ];
        let batch = RecordBatch::try_new(schema.clone(), columns).expect("batch");
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("t.parquet");
        write_batch(&path, &batch).expect("written");

        let builder = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(&path).unwrap())
            .expect("reader");
        let group = builder.metadata().row_group(0).clone();
        let encodings: Vec<(String, Vec<Encoding>)> = group
            .columns()
            .iter()
            .map(|c| {
                let data: Vec<Encoding> = c.encodings().filter(|e| *e != Encoding::RLE).collect();
                (c.column_path().string(), data)
            })
            .collect();
        let want = |e: Encoding| vec![e];
        assert_eq!(
            encodings,
            [
                ("t_ns".to_owned(), want(Encoding::DELTA_BINARY_PACKED)),
                ("seq".to_owned(), want(Encoding::DELTA_BINARY_PACKED)),
                ("pulses".to_owned(), want(Encoding::DELTA_BINARY_PACKED)),
                ("x".to_owned(), want(Encoding::BYTE_STREAM_SPLIT)),
                ("h_m".to_owned(), want(Encoding::BYTE_STREAM_SPLIT)),
                ("v.list.item".to_owned(), want(Encoding::BYTE_STREAM_SPLIT)),
                ("status".to_owned(), want(Encoding::PLAIN)),
            ]
        );
        // Equal arrays would call NaN unequal to itself: compare the bits.
        let read: Vec<RecordBatch> = builder
            .build()
            .expect("reader")
            .collect::<Result<_, _>>()
            .expect("read");
        let read = arrow::compute::concat_batches(&schema, &read).expect("one batch");
        assert_eq!(read.num_rows(), n);
        for (a, b) in batch.columns().iter().zip(read.columns()) {
            assert_eq!(a.to_data(), b.to_data(), "{:?}", a.data_type());
        }
        let bits = |b: &RecordBatch| -> Vec<u32> {
            let h = b.column(4).as_any().downcast_ref::<Float32Array>().unwrap();
            h.values().iter().map(|x| x.to_bits()).collect()
        };
        assert_eq!(bits(&batch), bits(&read));
        // 8 bytes a row plain; delta-encoded, a regular series is a few bytes a page.
        let t_bytes = group.column(0).compressed_size();
        assert!(t_bytes < 2_000, "{t_bytes} bytes for {n} regular times");
    }
}
