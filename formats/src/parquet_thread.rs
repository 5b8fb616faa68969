//! A [`ParquetSink`] on a thread of its own: the writer hands each batch over and goes
//! on while it is encoded and compressed, for a writer whose own work (reading a log,
//! say) would otherwise wait for every batch's encoding.

use std::path::PathBuf;
use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use arrow::array::RecordBatch;

use crate::error::{FileError, FormatError};
use crate::parquet_io::ParquetSink;

/// Batches handed over and not yet encoded, at most (bounds the memory the thread can
/// fall behind by).
const IN_FLIGHT: usize = 2;

/// What the thread receives: batches, then whether to commit the file.
enum Order {
    Write(RecordBatch),
    Finish,
}

/// A Parquet file written by its own thread; it appears under its name only on
/// [`ParquetThread::finish`], byte for byte the file the sink would write on the caller's.
pub struct ParquetThread {
    orders: Option<SyncSender<Order>>,
    thread: Option<JoinHandle<Result<(), FileError>>>,
    dest: PathBuf,
    rows: usize,
}

impl ParquetThread {
    /// Moves `sink` to a new thread named `name`.
    pub fn spawn(sink: ParquetSink, name: &str) -> Result<Self, FileError> {
        let dest = sink.dest().to_path_buf();
        let (orders, received) = sync_channel(IN_FLIGHT);
        let thread = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || {
                let mut sink = sink;
                for order in received {
                    match order {
                        Order::Write(batch) => sink.write(&batch)?,
                        Order::Finish => return sink.finish(),
                    }
                }
                // The writer stopped without finishing: the temporary file is dropped.
                Ok(())
            })
            .map_err(|e| crate::error::io_in_file(&dest, e))?;
        Ok(Self {
            orders: Some(orders),
            thread: Some(thread),
            dest,
            rows: 0,
        })
    }

    /// Hands `batch` over; an error is the thread's, from an earlier batch (it stopped).
    pub fn write(&mut self, batch: RecordBatch) -> Result<(), FileError> {
        self.rows += batch.num_rows();
        let sent = match &self.orders {
            Some(orders) => orders.send(Order::Write(batch)).is_ok(),
            None => false,
        };
        if sent { Ok(()) } else { self.stopped() }
    }

    /// Rows handed over so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Waits for every batch to be written, then closes the file and renames it into
    /// place.
    pub fn finish(mut self) -> Result<(), FileError> {
        if let Some(orders) = self.orders.take() {
            // An error here means the thread stopped: its result says why.
            let _ = orders.send(Order::Finish);
        }
        self.join()
    }

    /// The thread's error, once it stopped.
    fn stopped(&mut self) -> Result<(), FileError> {
        self.orders = None;
        self.join()?;
        Err(FormatError::Invalid("the Parquet writer thread stopped".into()).in_file(&self.dest))
    }

    fn join(&mut self) -> Result<(), FileError> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(
                FormatError::Invalid("the Parquet writer thread panicked".into())
                    .in_file(&self.dest),
            ),
            None => Ok(()),
        }
    }
}

impl Drop for ParquetThread {
    /// Without [`ParquetThread::finish`], the thread ends without committing the file.
    fn drop(&mut self) {
        self.orders = None;
        let _ = self.join();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    use arrow::array::{Float64Array, Int64Array};
    use arrow::datatypes::{DataType, Field, Schema};

    fn batch(from: i64, rows: i64) -> RecordBatch {
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("x", DataType::Float64, false),
        ]));
        RecordBatch::try_new(
            schema,
            vec![
                Arc::new(Int64Array::from_iter_values(from..from + rows)),
                Arc::new(Float64Array::from_iter_values(
                    (from..from + rows).map(|i| (i as f64 * 0.37).sin()),
                )),
            ],
        )
        .unwrap()
    }

    #[test]
    fn the_file_is_the_sinks_byte_for_byte() {
        let dir = tempfile::tempdir().unwrap();
        let batches: Vec<RecordBatch> = (0..5).map(|i| batch(i * 70_000, 70_000)).collect();
        let here = dir.path().join("here.parquet");
        let mut sink = ParquetSink::create_in_row_groups(&here, batches[0].schema(), 100_000)
            .unwrap()
            .on_this_thread();
        for b in &batches {
            sink.write(b).unwrap();
        }
        sink.finish().unwrap();
        let there = dir.path().join("there.parquet");
        let sink = ParquetSink::create_in_row_groups(&there, batches[0].schema(), 100_000).unwrap();
        let mut thread = ParquetThread::spawn(sink, "test").unwrap();
        for b in &batches {
            thread.write(b.clone()).unwrap();
        }
        assert_eq!(thread.rows(), 350_000);
        thread.finish().unwrap();
        assert_eq!(
            std::fs::read(&here).unwrap(),
            std::fs::read(&there).unwrap()
        );
    }

    /// A writer thread on `dir/t.parquet` for batches like `b`.
    fn thread_in(dir: &std::path::Path, b: &RecordBatch) -> ParquetThread {
        let sink = ParquetSink::create(&dir.join("t.parquet"), b.schema()).unwrap();
        ParquetThread::spawn(sink, "test").unwrap()
    }

    #[test]
    fn a_writer_dropped_unfinished_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let b = batch(0, 10);
        let mut thread = thread_in(dir.path(), &b);
        thread.write(b).unwrap();
        drop(thread);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_batch_the_sink_refuses_is_reported_with_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let good = batch(0, 10);
        let mut thread = thread_in(dir.path(), &good);
        // A batch of one column for a table of two: the thread stops on it.
        let bad = good.project(&[0]).unwrap();
        let mut error = None;
        for b in [bad, good.clone(), good.clone(), good.clone(), good] {
            if let Err(e) = thread.write(b) {
                error = Some(e);
                break;
            }
        }
        let error = match error {
            Some(e) => e,
            None => thread.finish().unwrap_err(),
        };
        let text = error.to_string();
        assert!(
            text.contains("t.parquet") && text.contains("columns"),
            "{text}"
        );
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
