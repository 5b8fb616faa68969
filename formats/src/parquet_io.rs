//! Parquet output (zstd, atomic) and input of whole tables.

use std::path::Path;

use arrow::array::RecordBatch;
use arrow::datatypes::DataType;
use arrow::datatypes::SchemaRef;
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use parquet::schema::types::ColumnPath;

use crate::atomic::AtomicFile;
use crate::error::{FileError, FormatError, io_in_file};

/// A Parquet file being written; it appears under its name only on [`ParquetSink::finish`].
pub struct ParquetSink {
    writer: ArrowWriter<std::fs::File>,
    file: AtomicFile,
    rows: usize,
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
        let file = AtomicFile::create(dest)?;
        // Sensor columns are high-cardinality floats: a dictionary never pays off and
        // page statistics are not used by any reader here; byte-stream-split floats
        // compress better and faster under zstd.
        let level = ZstdLevel::try_new(1).map_err(|e| parquet_err(dest, e))?;
        let mut builder = WriterProperties::builder()
            .set_compression(Compression::ZSTD(level))
            .set_max_row_group_row_count(Some(rows.max(1)))
            .set_dictionary_enabled(false)
            .set_statistics_enabled(EnabledStatistics::Chunk);
        for field in schema.fields() {
            let path = match field.data_type() {
                DataType::Float64 => Some(ColumnPath::new(vec![field.name().clone()])),
                DataType::FixedSizeList(item, _) if item.data_type() == &DataType::Float64 => {
                    Some(ColumnPath::new(vec![
                        field.name().clone(),
                        "list".into(),
                        item.name().clone(),
                    ]))
                }
                _ => None,
            };
            if let Some(path) = path {
                builder = builder.set_column_encoding(path, Encoding::BYTE_STREAM_SPLIT);
            }
        }
        let props = builder.build();
        let handle = file.file_handle()?;
        let writer =
            ArrowWriter::try_new(handle, schema, Some(props)).map_err(|e| parquet_err(dest, e))?;
        Ok(Self {
            writer,
            file,
            rows: 0,
        })
    }

    /// Writes one batch.
    pub fn write(&mut self, batch: &RecordBatch) -> Result<(), FileError> {
        self.rows += batch.num_rows();
        self.writer
            .write(batch)
            .map_err(|e| parquet_err(self.file.dest(), e))
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Closes the Parquet file and renames it into place.
    pub fn finish(self) -> Result<(), FileError> {
        let dest = self.file.dest().to_path_buf();
        self.writer.close().map_err(|e| parquet_err(&dest, e))?;
        self.file.commit()
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

/// How many rows to make room for before reading a Parquet file batch by batch: the
/// row count its footer states, but never more than the file's length in bytes, so that
/// a footer that lies cannot make a reader reserve more than the file's size says. It
/// is only a hint: the run-length files this pipeline reads hold many bytes per row, and
/// a reader's columns still grow past it if the file has more rows.
pub fn row_capacity_hint(path: &Path) -> Result<usize, FileError> {
    let file = std::fs::File::open(path).map_err(|e| io_in_file(path, e))?;
    let len = file.metadata().map_err(|e| io_in_file(path, e))?.len();
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| parquet_err(path, e))?;
    let rows = u64::try_from(builder.metadata().file_metadata().num_rows()).unwrap_or(0);
    Ok(usize::try_from(rows.min(len)).unwrap_or(0))
}

/// A reader of a Parquet file's batches (of 65 536 rows), and its schema; only the
/// top-level `columns` named, when given (a name the file lacks is left out).
fn batch_reader(
    path: &Path,
    columns: Option<&[&str]>,
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
    let reader = builder
        .with_batch_size(1 << 16)
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
    mut each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    for_each_batch_of_while(path, columns, |b| each(b).map(|()| true))
}

/// [`for_each_batch_of`] that stops, without decoding the rest, after the batch for
/// which `each` returns `false`.
pub fn for_each_batch_of_while(
    path: &Path,
    columns: &[&str],
    each: impl FnMut(&RecordBatch) -> Result<bool, FormatError>,
) -> Result<SchemaRef, FileError> {
    let (schema, reader) = batch_reader(path, Some(columns))?;
    feed(path, schema, reader, each)
}

/// Hands the batches of `reader` (reading `path`) to `each` until it returns `false`;
/// returns `schema`.
fn feed(
    path: &Path,
    schema: SchemaRef,
    reader: BatchReader,
    mut each: impl FnMut(&RecordBatch) -> Result<bool, FormatError>,
) -> Result<SchemaRef, FileError> {
    for batch in reader {
        let batch = batch.map_err(|e| parquet_err(path, e))?;
        if !each(&batch).map_err(|e| e.in_file(path))? {
            break;
        }
    }
    Ok(schema)
}

/// Reads a Parquet file batch by batch, handing each to `each`: a whole run's columns
/// are built without the file's batches held beside them. Returns the schema.
pub fn for_each_batch(
    path: &Path,
    mut each: impl FnMut(&RecordBatch) -> Result<(), FormatError>,
) -> Result<SchemaRef, FileError> {
    let (schema, reader) = batch_reader(path, None)?;
    feed(path, schema, reader, |b| each(b).map(|()| true))
}

/// Reads a whole Parquet file: its schema and batches.
pub fn read_batches(path: &Path) -> Result<(SchemaRef, Vec<RecordBatch>), FileError> {
    let (schema, reader) = batch_reader(path, None)?;
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
    use arrow::array::Float64Array;
    use arrow::datatypes::{Field, Schema};
    use std::sync::Arc;

    #[test]
    fn the_row_hint_is_the_footers_count_within_the_files_size() {
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
        // A constant column compresses to fewer bytes than rows: the file's size bounds
        // the hint, and reading still gives every row.
        let flat = write("flat.parquet", vec![1.0; 200_000]);
        let bytes = std::fs::metadata(&flat).expect("size").len() as usize;
        assert!(bytes < 200_000);
        assert_eq!(row_capacity_hint(&flat).expect("hint"), bytes);
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
}
