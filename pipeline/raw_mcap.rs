//! `raw.mcap`: the raw log as ROS 2 messages for Foxglove and Rerun (`/imu` at the log's
//! rate, `/odometer` at most at 10 Hz, `/marks`), written on a thread of its own so that
//! its encoding and compression overlap the reader and the Parquet encoders.
//!
//! The odometer is thinned to 10 Hz for viewing: a speed from the pulses of one 10 ms
//! sample is quantised to a pulse per 10 ms (a 2 m/s step at 2 cm per pulse), and 0.1 s
//! gives a readable speed. The exact pulses are in `odometer.parquet`.

use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, SyncSender, channel, sync_channel};
use std::thread::JoinHandle;

use unz_formats::mcap_io::{Channel, McapCompression, Ros2Mcap};
use unz_formats::ros2_msgs::{ControlPointMark, ImuSample, OdometerSample};

/// Messages in the first batch handed to the writer thread; each batch after it holds
/// twice as many as the one before, up to [`BATCH_MAX`]. The small first batch starts the
/// thread early. Large batches after it cost less CPU where the host is slow: at 8 192
/// messages throughout (460 KB a batch, about 30 for a 40-minute log) the full ingest
/// took 157–224 MB/s and a median of 0.1025 s of CPU a pass; growing to 65 536, 190–217
/// MB/s and 0.093 s (16 benches alternately, session 96; 2–3 % slower in the host's quick
/// spells, up to a fifth quicker in its slow ones). The slack was not the cause: 32
/// batches of 8 192 in flight measured as 4. The same bytes are written either way.
const BATCH_FIRST: usize = 8192;
/// Messages in a batch once grown (about 3.7 MB).
const BATCH_MAX: usize = 65_536;
/// Batches in flight (bounds the memory the thread can fall behind by: with the batch
/// being filled, the one being written and those given back, at most six batches, about
/// 22 MB, as a batch is made only when none is given back). Two in flight made the
/// reading wait for the thread (a slower ingest than 8 192-message batches).
const IN_FLIGHT: usize = 4;
/// Shortest interval between two `/odometer` messages, ns.
const ODOMETER_VIEW_PERIOD_NS: i64 = 100_000_000;

/// One message, with the run's time of its sample.
enum Item {
    Imu(i64, ImuSample),
    Odometer(i64, OdometerSample),
    Mark(i64, u32),
}

/// What the writer thread receives: messages, then whether to commit the file.
enum Order {
    Write(Vec<Item>),
    Commit,
}

/// The writer's side of `raw.mcap`, on its thread.
struct RawMcap {
    mcap: Ros2Mcap,
    imu: Channel<ImuSample>,
    odo: Channel<OdometerSample>,
    marks: Channel<ControlPointMark>,
    origin_ns: i64,
}

impl RawMcap {
    fn log_time(&self, t_ns: i64) -> u64 {
        u64::try_from(self.origin_ns.saturating_add(t_ns)).unwrap_or(0)
    }

    fn write(&mut self, item: Item) -> anyhow::Result<()> {
        match item {
            Item::Imu(t_ns, msg) => {
                let lt = self.log_time(t_ns);
                self.mcap.write(&mut self.imu, lt, &msg)?;
            }
            Item::Odometer(t_ns, msg) => {
                let lt = self.log_time(t_ns);
                self.mcap.write(&mut self.odo, lt, &msg)?;
            }
            Item::Mark(t_ns, point_id) => {
                let lt = self.log_time(t_ns);
                self.mcap
                    .write(&mut self.marks, lt, &ControlPointMark { point_id })?;
            }
        }
        Ok(())
    }

    /// Writes every batch received, handing the emptied batches back; commits the file
    /// only when told to.
    fn run(mut self, orders: Receiver<Order>, empties: Sender<Vec<Item>>) -> anyhow::Result<()> {
        for order in orders {
            match order {
                Order::Write(mut items) => {
                    for item in items.drain(..) {
                        self.write(item)?;
                    }
                    // The ingest may have finished already: then nobody needs it back.
                    let _ = empties.send(items);
                }
                // Its hash, taken as it was written, is remembered
                // (`file_hashes::remember_written`).
                Order::Commit => return Ok(self.mcap.finish()?),
            }
        }
        // The ingest stopped without committing: the temporary file is dropped.
        Ok(())
    }
}

/// `raw.mcap` being written by its thread; messages are queued in batches.
pub struct RawMcapWriter {
    batch: Vec<Item>,
    /// Messages the batch being filled is handed over at.
    batch_len: usize,
    orders: Option<SyncSender<Order>>,
    /// Batches the thread has written, to fill again (fresh batches cost page faults and
    /// cache misses that tripled the stage's time).
    empties: Receiver<Vec<Item>>,
    thread: Option<JoinHandle<anyhow::Result<()>>>,
    /// Time and distance of the last `/odometer` message.
    last_odo: Option<(i64, f64)>,
}

impl RawMcapWriter {
    /// Creates `path` (errors here are immediate) and starts its writer thread. Log times
    /// are `origin_ns` (the log's UTC start, or 0) plus each sample's run time.
    pub fn create(
        path: &Path,
        origin_ns: i64,
        compression: McapCompression,
    ) -> anyhow::Result<Self> {
        let mut mcap = Ros2Mcap::create(path, compression)?;
        let writer = RawMcap {
            imu: mcap.add_channel("/imu")?,
            odo: mcap.add_channel("/odometer")?,
            marks: mcap.add_channel("/marks")?,
            mcap,
            origin_ns,
        };
        let (orders, receiver) = sync_channel(IN_FLIGHT);
        let (give_back, empties) = channel();
        let thread = std::thread::Builder::new()
            .name("raw.mcap".into())
            .spawn(move || writer.run(receiver, give_back))?;
        Ok(Self {
            batch: Vec::with_capacity(BATCH_FIRST),
            batch_len: BATCH_FIRST,
            orders: Some(orders),
            empties,
            thread: Some(thread),
            last_odo: None,
        })
    }

    /// Queues one IMU sample: its increments over `dt_s` as rates.
    pub fn imu(
        &mut self,
        t_ns: i64,
        dt_s: f64,
        seq: u64,
        dtheta: [f64; 3],
        dvel: [f64; 3],
        status: u16,
    ) {
        let inv = if dt_s > 0.0 { 1.0 / dt_s } else { 0.0 };
        let msg = ImuSample {
            seq,
            status,
            rate_rad_s: dtheta.map(|v| (v * inv) as f32),
            accel_mps2: dvel.map(|v| (v * inv) as f32),
        };
        self.push(Item::Imu(t_ns, msg));
    }

    /// Queues one odometer sample when 0.1 s has passed since the last one queued, with
    /// the speed over that interval.
    pub fn odometer(&mut self, t_ns: i64, distance_m: f64) {
        let speed_mps = match self.last_odo {
            // Time went back (a damaged log): start again from this sample.
            Some((t0, _)) if t_ns < t0 => 0.0,
            // Saturating: tags 292 years apart (a damaged text log's) overflow an i64.
            Some((t0, _)) if t_ns.saturating_sub(t0) < ODOMETER_VIEW_PERIOD_NS => return,
            Some((t0, d0)) => (distance_m - d0) / (t_ns.saturating_sub(t0) as f64 * 1e-9),
            None => 0.0,
        };
        self.last_odo = Some((t_ns, distance_m));
        let msg = OdometerSample {
            distance_m,
            speed_mps,
        };
        self.push(Item::Odometer(t_ns, msg));
    }

    /// Queues a control-point mark.
    pub fn mark(&mut self, t_ns: i64, point_id: u32) {
        self.push(Item::Mark(t_ns, point_id));
    }

    fn push(&mut self, item: Item) {
        self.batch.push(item);
        if self.batch.len() >= self.batch_len {
            self.send();
        }
    }

    /// Hands the batch over; the next, twice as long up to [`BATCH_MAX`], is filled in
    /// one the thread gave back if it has room for it (one of the first, shorter
    /// batches is let go).
    fn send(&mut self) {
        self.batch_len = (2 * self.batch_len).min(BATCH_MAX);
        let next = match self.empties.try_recv() {
            Ok(empty) if empty.capacity() >= self.batch_len => empty,
            _ => Vec::with_capacity(self.batch_len),
        };
        let items = std::mem::replace(&mut self.batch, next);
        self.hand_over(items);
    }

    /// Queues `items` for the thread.
    fn hand_over(&mut self, items: Vec<Item>) {
        // A closed channel means the thread stopped on an error: `finish` reports it.
        if let Some(orders) = &self.orders
            && orders.send(Order::Write(items)).is_err()
        {
            self.orders = None;
        }
    }

    /// Writes what is queued, the summary, and renames the file into place; the thread's
    /// first error if it had one.
    pub fn finish(mut self) -> anyhow::Result<()> {
        // The last batch, with no next one to fill.
        let items = std::mem::take(&mut self.batch);
        self.hand_over(items);
        if let Some(orders) = self.orders.take() {
            // An error here means the thread already stopped: its result says why.
            let _ = orders.send(Order::Commit);
        }
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => anyhow::bail!("the raw.mcap writer thread panicked"),
            None => Ok(()),
        }
    }
}

impl Drop for RawMcapWriter {
    /// Without `finish` (the ingest failed), the thread ends without committing the file.
    fn drop(&mut self) {
        self.orders = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression (fuzzing the text ingest): odometer readings whose time tags were more
    /// than 292 years apart overflowed the interval between them (a panic in a debug
    /// build, a wrapped interval and a skipped message in a release one).
    #[test]
    fn odometer_tags_an_i64_apart_give_their_messages() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("raw.mcap");
        let mut w = RawMcapWriter::create(&path, 0, McapCompression::default()).unwrap();
        w.odometer(i64::MIN + 1, 0.0);
        w.odometer(i64::MAX, 5.0);
        let speeds: Vec<f64> = (w.batch.iter())
            .map(|item| match item {
                Item::Odometer(_, m) => m.speed_mps,
                _ => panic!("an odometer message expected"),
            })
            .collect();
        assert_eq!(speeds.len(), 2);
        // 5 m over the i64's span, saturated: 9.2e18 ns.
        assert!(speeds[1] > 0.0 && speeds[1] < 1e-9, "{speeds:?}");
        w.finish().unwrap();
    }

    /// The batches grow from [`BATCH_FIRST`] to [`BATCH_MAX`] messages and stay there;
    /// every message queued is written once, in order.
    #[test]
    fn batches_grow_to_their_largest_and_lose_no_message() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("raw.mcap");
        let mut w = RawMcapWriter::create(&path, 0, McapCompression::default()).unwrap();
        let mut handed = Vec::new();
        let n = 300_000u64;
        for k in 0..n {
            let before = w.batch.len();
            w.imu(k as i64 * 10_000_000, 0.01, k, [0.0; 3], [0.0; 3], 0);
            if w.batch.len() < before + 1 {
                handed.push(before + 1);
            }
        }
        assert_eq!(
            handed,
            [8192, 16_384, 32_768, 65_536, 65_536, 65_536],
            "batch lengths handed over"
        );
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let seqs: Vec<u64> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                // CDR: a 4-byte encapsulation header, then `seq`.
                u64::from_le_bytes(m.data[4..12].try_into().unwrap())
            })
            .collect();
        assert_eq!(seqs, (0..n).collect::<Vec<_>>());
    }

    /// The file's hash is taken as it is written (more than one chunk here) and
    /// remembered for its stage's record, which then does not read the file back: before,
    /// a 12-hour run's 405 MB were read again, 0.2 s on one core at the ingest's end.
    #[test]
    fn the_files_hash_is_remembered_as_written() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("raw.mcap");
        let mut w = RawMcapWriter::create(&path, 7, McapCompression::default()).unwrap();
        for k in 0..60_000i64 {
            w.imu(
                k * 10_000_000,
                0.01,
                k as u64,
                [1e-5; 3],
                [0.098, 0.0, -0.098],
                0,
            );
            w.odometer(k * 10_000_000, k as f64 * 0.1);
        }
        w.mark(123, 4);
        crate::file_hashes::remember_what_formats_write();
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.len() > 2 << 20, "{} bytes: one chunk", bytes.len());
        let want = blake3::hash(&bytes).to_hex().to_string();
        assert_eq!(crate::file_hashes::remembered(&path), Some(want));
    }
}
