//! Some rows of a table's float columns: the rows a reader keeps of a 100-Hz table (the
//! review's every n-th, the export's one each 0.1 s), without the other rows widened or
//! copied.

use std::path::Path;

use arrow::datatypes::{DataType, Int64Type};
use unz_formats::parquet_io::{for_each_batch_of, read_schema};
use unz_formats::split_doubles::for_each_split_page;
use unz_formats::tables::{float_values, values_of};

/// The rows `rows` (increasing indices) of each f64 or f32 column `names` of the table at
/// `path`, f32 widened exactly: each column's pages with their byte streams joined
/// ([`for_each_split_page`]) where its layout is the tables' (BYTE_STREAM_SPLIT, no
/// nulls), else all the columns through Arrow, batch by batch. A row past the table's
/// end is an error naming the file.
pub fn picked_columns(
    path: &Path,
    names: &[&str],
    rows: &[usize],
) -> anyhow::Result<Vec<Vec<f64>>> {
    anyhow::ensure!(
        rows.windows(2).all(|w| w[0] < w[1]),
        "rows picked out of order from {}",
        path.display()
    );
    match picked_split_columns(path, names, rows)? {
        Some(columns) => Ok(columns),
        None => picked_arrow_columns(path, names, rows),
    }
}

/// [`picked_columns`] through Arrow.
fn picked_arrow_columns(
    path: &Path,
    names: &[&str],
    rows: &[usize],
) -> anyhow::Result<Vec<Vec<f64>>> {
    let mut out = vec![Vec::with_capacity(rows.len()); names.len()];
    let (mut first, mut next) = (0, 0);
    for_each_batch_of(path, names, |b| {
        let columns = names
            .iter()
            .map(|n| float_values(b, n))
            .collect::<Result<Vec<_>, _>>()?;
        let end = first + b.num_rows();
        while let Some(&k) = rows.get(next).filter(|&&k| k < end) {
            for (o, c) in out.iter_mut().zip(&columns) {
                o.push(c.get(k - first));
            }
            next += 1;
        }
        first = end;
        Ok(())
    })?;
    anyhow::ensure!(
        next == rows.len(),
        "{}: row {} picked of {first}",
        path.display(),
        rows[next]
    );
    Ok(out)
}

/// [`picked_columns`] page by page; `None` when a column is not of the tables' layout.
fn picked_split_columns(
    path: &Path,
    names: &[&str],
    rows: &[usize],
) -> anyhow::Result<Option<Vec<Vec<f64>>>> {
    let schema = read_schema(path)?;
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let mut column = Vec::with_capacity(rows.len());
        let mut next = 0;
        let mut keep = |first: usize, n: usize, value: &dyn Fn(usize) -> f64| {
            while let Some(&k) = rows.get(next).filter(|&&k| k < first + n) {
                // A page starts where the one before ended: no row is skipped.
                column.push(value(k - first));
                next += 1;
            }
        };
        let whole = match schema.field_with_name(name).map(|f| f.data_type()) {
            Ok(DataType::Float64) => for_each_split_page::<f64>(path, name, |first, v| {
                keep(first, v.len(), &|i| v[i]);
            })?,
            Ok(DataType::Float32) => for_each_split_page::<f32>(path, name, |first, v| {
                keep(first, v.len(), &|i| f64::from(v[i]));
            })?,
            _ => false,
        };
        if !whole {
            return Ok(None);
        }
        anyhow::ensure!(
            column.len() == rows.len(),
            "{}: row {} of {name} picked past the table's end",
            path.display(),
            rows[column.len()]
        );
        out.push(column);
    }
    Ok(Some(out))
}

/// The rows of `samples` (any order, repeats allowed) below `rows`, increasing and each
/// once: what [`picked_columns`] takes of a table of `rows` rows.
pub fn rows_among(samples: &[usize], rows: usize) -> Vec<usize> {
    let mut picked: Vec<usize> = samples.iter().copied().filter(|&s| s < rows).collect();
    picked.sort_unstable();
    picked.dedup();
    picked
}

/// The `t_ns` of the rows of the table at `path` that `keep(row, t_ns)` takes (asked of
/// every row in turn), their indices, and the table's rows.
pub fn picked_times(
    path: &Path,
    mut keep: impl FnMut(usize, i64) -> bool,
) -> anyhow::Result<(Vec<i64>, Vec<usize>, usize)> {
    let (mut t, mut rows, mut n) = (Vec::new(), Vec::new(), 0);
    for_each_batch_of(path, &[unz_formats::schema::T_NS], |b| {
        let tb = values_of::<Int64Type>(b, unz_formats::schema::T_NS)?;
        for (k, &tk) in tb.iter().enumerate() {
            if keep(n + k, tk) {
                t.push(tk);
                rows.push(n + k);
            }
        }
        n += tb.len();
        Ok(())
    })?;
    Ok((t, rows, n))
}

/// A copy at `dest` of the table at `path` in Arrow's default encodings (plain and
/// dictionary, no byte-stream split): a table the split readers leave to Arrow.
#[cfg(test)]
pub(crate) fn plain_copy(path: &Path, dest: &Path) {
    let (schema, batches) = unz_formats::parquet_io::read_batches(path).unwrap();
    let file = std::fs::File::create(dest).unwrap();
    let mut w = parquet::arrow::ArrowWriter::try_new(file, schema, None).unwrap();
    for b in &batches {
        w.write(b).unwrap();
    }
    w.close().unwrap();
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use arrow::array::{Float32Array, Float64Array, Int64Array, RecordBatch};
    use arrow::datatypes::{Field, Schema};
    use parquet::arrow::ArrowWriter;
    use parquet::file::properties::WriterProperties;

    use super::*;

    /// A table of `n` rows over several pages, written by the tables' writer (split
    /// floats) or by Arrow's with its plain defaults.
    fn table(dir: &Path, n: usize, split: bool) -> (std::path::PathBuf, Vec<f64>, Vec<f32>) {
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", arrow::datatypes::DataType::Int64, false),
            Field::new("a", arrow::datatypes::DataType::Float64, false),
            Field::new("h", arrow::datatypes::DataType::Float32, false),
        ]));
        let a: Vec<f64> = (0..n).map(|k| (k as f64).sqrt() - 3.0).collect();
        let h: Vec<f32> = (0..n).map(|k| (k as f32).cbrt() - 9.0).collect();
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![
                Arc::new(Int64Array::from_iter_values((0..n).map(|k| 10 * k as i64))),
                Arc::new(Float64Array::from(a.clone())),
                Arc::new(Float32Array::from(h.clone())),
            ],
        )
        .unwrap();
        let path = dir.join(if split {
            "split.parquet"
        } else {
            "plain.parquet"
        });
        if split {
            unz_formats::parquet_io::write_batch(&path, &batch).unwrap();
        } else {
            let props = WriterProperties::builder()
                .set_data_page_row_count_limit(1000)
                .set_write_batch_size(1000)
                .build();
            let mut w =
                ArrowWriter::try_new(std::fs::File::create(&path).unwrap(), schema, Some(props))
                    .unwrap();
            w.write(&batch).unwrap();
            w.close().unwrap();
        }
        (path, a, h)
    }

    /// Both routes give the rows picked, bit for bit, the f32 widened: every 7th, a
    /// time rule (the first row at or past each 0.1 s), the last row alone, none.
    #[test]
    fn picked_rows_are_the_tables_rows_either_way() {
        let tmp = tempfile::tempdir().unwrap();
        let n = 150_001;
        for split in [true, false] {
            let (path, a, h) = table(tmp.path(), n, split);
            let mut next = None;
            let (t, by_time, total) = picked_times(&path, |_, tk| {
                if next.is_some_and(|nx| tk < nx) {
                    return false;
                }
                next = Some(tk + 95);
                true
            })
            .unwrap();
            assert_eq!(total, n);
            // The tables' writer's file goes page by page, Arrow's plain one through Arrow.
            assert_eq!(
                picked_split_columns(&path, &["a", "h"], &[0])
                    .unwrap()
                    .is_some(),
                split
            );
            assert_eq!(
                t,
                by_time.iter().map(|&k| 10 * k as i64).collect::<Vec<_>>()
            );
            for picked in [(0..n).step_by(7).collect(), by_time, vec![n - 1], vec![]] {
                let got = picked_columns(&path, &["a", "h"], &picked).unwrap();
                let want_a: Vec<u64> = picked.iter().map(|&k| a[k].to_bits()).collect();
                let want_h: Vec<u64> = picked.iter().map(|&k| f64::from(h[k]).to_bits()).collect();
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got[0]), want_a, "split {split}");
                assert_eq!(bits(&got[1]), want_h, "split {split}");
            }
            // A row past the end, or rows out of order: errors naming the file.
            for bad in [vec![3, n], vec![5, 4]] {
                let err = picked_columns(&path, &["a"], &bad).unwrap_err();
                assert!(format!("{err:#}").contains(".parquet"), "{err:#}");
            }
        }
    }
}
