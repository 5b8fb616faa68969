//! In-memory column tables of the canonical schemas, and their Arrow conversions.

use std::sync::Arc;

use arrow::array::{
    Array, ArrayRef, AsArray, BooleanArray, FixedSizeListArray, Float64Array, Int64Array,
    RecordBatch, UInt8Array, UInt16Array, UInt32Array, UInt64Array,
};
use arrow::buffer::ScalarBuffer;
use arrow::datatypes::{
    Float32Type, Float64Type, Int64Type, SchemaRef, UInt8Type, UInt16Type, UInt32Type, UInt64Type,
};

use crate::error::FormatError;
use crate::schema;

/// IMU samples (schema [`schema::imu`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuTable {
    /// Time at the end of each interval, ns.
    pub t_ns: Vec<i64>,
    /// Unwrapped sample counter.
    pub seq: Vec<u64>,
    /// Angle increments, rad, body FRD.
    pub dtheta_rad: Vec<[f64; 3]>,
    /// Velocity increments, m/s, body FRD.
    pub dvel_mps: Vec<[f64; 3]>,
    /// Status bits.
    pub status: Vec<u16>,
}

/// Odometer samples (schema [`schema::odometer`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OdometerTable {
    /// Time, ns.
    pub t_ns: Vec<i64>,
    /// Cumulative distance, m.
    pub distance_m: Vec<f64>,
    /// Cumulative pulses, when counted.
    pub pulses: Vec<Option<i64>>,
    /// Where each distance comes from ([`schema::DistanceSource`]'s codes).
    pub source: Vec<u8>,
}

/// Control-point marks (schema [`schema::marks`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarksTable {
    /// Time, ns.
    pub t_ns: Vec<i64>,
    /// Control-point id.
    pub point_id: Vec<u32>,
}

fn vec3_array(v: &[[f64; 3]]) -> ArrayRef {
    vec3_array_of(v.as_flattened().to_vec())
}

/// A `FixedSizeList<Float64, 3>` of flat x, y, z values.
fn vec3_array_of(flat: Vec<f64>) -> ArrayRef {
    let values = Arc::new(Float64Array::new(ScalarBuffer::from(flat), None));
    let item = Arc::new(arrow::datatypes::Field::new(
        "item",
        arrow::datatypes::DataType::Float64,
        false,
    ));
    Arc::new(FixedSizeListArray::new(item, 3, values, None))
}

fn batch(schema: SchemaRef, columns: Vec<ArrayRef>) -> Result<RecordBatch, FormatError> {
    RecordBatch::try_new(schema, columns).map_err(|e| FormatError::Invalid(e.to_string()))
}

fn column<'a>(b: &'a RecordBatch, name: &str) -> Result<&'a ArrayRef, FormatError> {
    b.column_by_name(name)
        .ok_or_else(|| FormatError::Invalid(format!("column {name:?} is missing")))
}

fn prim<'a, T: arrow::datatypes::ArrowPrimitiveType>(
    b: &'a RecordBatch,
    name: &str,
) -> Result<&'a arrow::array::PrimitiveArray<T>, FormatError> {
    column(b, name)?.as_primitive_opt::<T>().ok_or_else(|| {
        FormatError::Invalid(format!(
            "column {name:?} has type {}",
            column(b, name)
                .map(|c| c.data_type().to_string())
                .unwrap_or_default()
        ))
    })
}

/// A batch's 3-vector column `name` (a fixed-size list of three Float64), as arrays.
pub fn vec3_values(b: &RecordBatch, name: &str) -> Result<Vec<[f64; 3]>, FormatError> {
    let list = column(b, name)?
        .as_fixed_size_list_opt()
        .filter(|l| l.value_length() == 3)
        .ok_or_else(|| FormatError::Invalid(format!("column {name:?} is not a 3-vector")))?;
    let values = list
        .values()
        .as_primitive_opt::<Float64Type>()
        .ok_or_else(|| FormatError::Invalid(format!("column {name:?} is not Float64")))?;
    let start = list.offset() * 3;
    let v = &values.values()[start..start + list.len() * 3];
    Ok(v.as_chunks::<3>().0.to_vec())
}

/// Moves `v`'s values out, leaving it empty with room for as many: a table filled and
/// taken batch by batch then fills its next batch without growing (each doubling of a
/// 64-k-row column copied what it held: 0.5 % of a campaign's CPU in the ingest).
fn take_with_room<T>(v: &mut Vec<T>) -> Vec<T> {
    let room = v.capacity();
    std::mem::replace(v, Vec::with_capacity(room))
}

impl ImuTable {
    /// Empty, with room for `rows` rows.
    pub fn with_room(rows: usize) -> Self {
        Self {
            t_ns: Vec::with_capacity(rows),
            seq: Vec::with_capacity(rows),
            dtheta_rad: Vec::with_capacity(rows),
            dvel_mps: Vec::with_capacity(rows),
            status: Vec::with_capacity(rows),
        }
    }

    /// Converts to a record batch, moving the columns out (the table is left empty, with
    /// room for as many rows; the vectors' x, y, z become the arrays' values without a
    /// copy).
    pub fn take_batch(&mut self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        let flat = |v: Vec<[f64; 3]>| vec3_array_of(v.into_flattened());
        batch(
            schema,
            vec![
                Arc::new(Int64Array::from(take_with_room(&mut self.t_ns))),
                Arc::new(UInt64Array::from(take_with_room(&mut self.seq))),
                flat(take_with_room(&mut self.dtheta_rad)),
                flat(take_with_room(&mut self.dvel_mps)),
                Arc::new(UInt16Array::from(take_with_room(&mut self.status))),
            ],
        )
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_ns.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_ns.is_empty()
    }

    /// Empties the table, keeping its capacity.
    pub fn clear(&mut self) {
        self.t_ns.clear();
        self.seq.clear();
        self.dtheta_rad.clear();
        self.dvel_mps.clear();
        self.status.clear();
    }

    /// Converts to a record batch of `schema` (from [`schema::imu`]).
    pub fn to_batch(&self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        batch(
            schema,
            vec![
                Arc::new(Int64Array::from(self.t_ns.clone())),
                Arc::new(UInt64Array::from(self.seq.clone())),
                vec3_array(&self.dtheta_rad),
                vec3_array(&self.dvel_mps),
                Arc::new(UInt16Array::from(self.status.clone())),
            ],
        )
    }

    /// Appends the rows of a batch.
    pub fn extend_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.seq
            .extend(prim::<UInt64Type>(b, schema::SEQ)?.values().iter());
        self.extend_series_from_batch(b)
    }

    /// The columns a derive reads (not `seq`): what [`ImuTable::extend_series_from_batch`]
    /// takes.
    pub const SERIES_COLUMNS: [&str; 4] = [
        schema::T_NS,
        schema::DTHETA_RAD,
        schema::DVEL_MPS,
        schema::STATUS,
    ];

    /// Empty, with room for `rows` rows of [`ImuTable::SERIES_COLUMNS`].
    pub fn with_series_capacity(rows: usize) -> Self {
        Self {
            t_ns: Vec::with_capacity(rows),
            seq: Vec::new(),
            dtheta_rad: Vec::with_capacity(rows),
            dvel_mps: Vec::with_capacity(rows),
            status: Vec::with_capacity(rows),
        }
    }

    /// Appends the rows of a batch of [`ImuTable::SERIES_COLUMNS`] (`seq` stays empty).
    pub fn extend_series_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.t_ns
            .extend(prim::<Int64Type>(b, schema::T_NS)?.values().iter());
        self.dtheta_rad.extend(vec3_values(b, schema::DTHETA_RAD)?);
        self.dvel_mps.extend(vec3_values(b, schema::DVEL_MPS)?);
        self.status
            .extend(prim::<UInt16Type>(b, schema::STATUS)?.values().iter());
        Ok(())
    }
}

impl OdometerTable {
    /// Empty, with room for `rows` rows.
    pub fn with_room(rows: usize) -> Self {
        Self {
            t_ns: Vec::with_capacity(rows),
            distance_m: Vec::with_capacity(rows),
            pulses: Vec::with_capacity(rows),
            source: Vec::with_capacity(rows),
        }
    }

    /// Converts to a record batch, moving the columns out (the table is left empty, with
    /// room for as many rows).
    pub fn take_batch(&mut self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        batch(
            schema,
            vec![
                Arc::new(Int64Array::from(take_with_room(&mut self.t_ns))),
                Arc::new(Float64Array::from(take_with_room(&mut self.distance_m))),
                Arc::new(Int64Array::from(take_with_room(&mut self.pulses))),
                Arc::new(UInt8Array::from(take_with_room(&mut self.source))),
            ],
        )
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_ns.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_ns.is_empty()
    }

    /// Empties the table, keeping its capacity.
    pub fn clear(&mut self) {
        self.t_ns.clear();
        self.distance_m.clear();
        self.pulses.clear();
        self.source.clear();
    }

    /// Converts to a record batch of `schema` (from [`schema::odometer`]).
    pub fn to_batch(&self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        batch(
            schema,
            vec![
                Arc::new(Int64Array::from(self.t_ns.clone())),
                Arc::new(Float64Array::from(self.distance_m.clone())),
                Arc::new(Int64Array::from(self.pulses.clone())),
                Arc::new(UInt8Array::from(self.source.clone())),
            ],
        )
    }

    /// Appends the rows of a batch.
    pub fn extend_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.pulses
            .extend(prim::<Int64Type>(b, schema::PULSES)?.iter());
        self.source.extend(
            prim::<UInt8Type>(b, schema::DISTANCE_SOURCE)?
                .values()
                .iter(),
        );
        self.extend_series_from_batch(b)
    }

    /// The columns a derive reads (not `pulses`): what
    /// [`OdometerTable::extend_series_from_batch`] takes.
    pub const SERIES_COLUMNS: [&str; 2] = [schema::T_NS, schema::DISTANCE_M];

    /// Empty, with room for `rows` rows of [`OdometerTable::SERIES_COLUMNS`].
    pub fn with_series_capacity(rows: usize) -> Self {
        Self {
            t_ns: Vec::with_capacity(rows),
            distance_m: Vec::with_capacity(rows),
            pulses: Vec::new(),
            source: Vec::new(),
        }
    }

    /// Appends the rows of a batch of [`OdometerTable::SERIES_COLUMNS`] (`pulses` stays
    /// empty).
    pub fn extend_series_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.t_ns
            .extend(prim::<Int64Type>(b, schema::T_NS)?.values().iter());
        self.distance_m
            .extend(prim::<Float64Type>(b, schema::DISTANCE_M)?.values().iter());
        Ok(())
    }
}

impl MarksTable {
    /// Converts to a record batch of `schema` (from [`schema::marks`]).
    pub fn to_batch(&self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        batch(
            schema,
            vec![
                Arc::new(Int64Array::from(self.t_ns.clone())),
                Arc::new(UInt32Array::from(self.point_id.clone())),
            ],
        )
    }

    /// Appends the rows of a batch.
    pub fn extend_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.t_ns
            .extend(prim::<Int64Type>(b, schema::T_NS)?.values().iter());
        self.point_id
            .extend(prim::<UInt32Type>(b, schema::POINT_ID)?.values().iter());
        Ok(())
    }
}

/// A batch's `Float64` or `Float32` column where it lies, each value widened to f64 as it
/// is read ([`f64_column`] without copying the column: for a reader that keeps a few of
/// its rows).
#[derive(Debug, Clone, Copy)]
pub enum FloatValues<'a> {
    /// A `Float64` column's values.
    F64(&'a [f64]),
    /// A `Float32` column's values.
    F32(&'a [f32]),
}

impl FloatValues<'_> {
    /// Row `k`'s value (exactly, from either width).
    pub fn get(&self, k: usize) -> f64 {
        match self {
            FloatValues::F64(v) => v[k],
            FloatValues::F32(v) => f64::from(v[k]),
        }
    }
}

/// The `Float64` or `Float32` column `name` of a batch, in place.
pub fn float_values<'a>(b: &'a RecordBatch, name: &str) -> Result<FloatValues<'a>, FormatError> {
    if let Some(c) = column(b, name)?.as_primitive_opt::<Float32Type>() {
        return Ok(FloatValues::F32(c.values()));
    }
    Ok(FloatValues::F64(prim::<Float64Type>(b, name)?.values()))
}

/// Reads a `Float64` column of a batch; single-precision columns (the navigation's
/// attitude, local positions, σ) widen exactly.
pub fn f64_column(b: &RecordBatch, name: &str) -> Result<Vec<f64>, FormatError> {
    Ok(match float_values(b, name)? {
        FloatValues::F64(v) => v.to_vec(),
        FloatValues::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
    })
}

/// The criteria at the ΔTg epochs (schema [`schema::criteria`], `criteria.parquet`):
/// written by the criteria stage, read by export and review.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CriteriaTable {
    /// Epoch time, ns in the log's time base.
    pub t_ns: Vec<i64>,
    /// Filtered gyro (navigated) pitch Θ_N, rad.
    pub theta_n_rad: Vec<f64>,
    /// Filtered gyro roll Φ_N, rad.
    pub phi_n_rad: Vec<f64>,
    /// Accelerometer pitch Θ_p, rad.
    pub theta_p_rad: Vec<f64>,
    /// Accelerometer roll Φ_p, rad.
    pub phi_p_rad: Vec<f64>,
    /// Θ_N − Θ_p, rad.
    pub d_theta_rad: Vec<f64>,
    /// Φ_N − Φ_p (wrapped), rad.
    pub d_phi_rad: Vec<f64>,
    /// The Kalman filter's estimate of the pitch difference, rad.
    pub kf_d_theta_rad: Vec<f64>,
    /// The Kalman filter's estimate of the roll difference, rad.
    pub kf_d_phi_rad: Vec<f64>,
    /// Kryt1 accumulated up to the epoch, rad.
    pub kryt1_cum: Vec<f64>,
    /// Whether the epoch was used (not gated).
    pub valid: Vec<bool>,
}

impl CriteriaTable {
    /// The float columns, in the order of [`schema::CRITERIA_FLOATS`].
    fn floats(&self) -> [&Vec<f64>; 9] {
        [
            &self.theta_n_rad,
            &self.phi_n_rad,
            &self.theta_p_rad,
            &self.phi_p_rad,
            &self.d_theta_rad,
            &self.d_phi_rad,
            &self.kf_d_theta_rad,
            &self.kf_d_phi_rad,
            &self.kryt1_cum,
        ]
    }

    /// [`CriteriaTable::floats`], to extend.
    fn floats_mut(&mut self) -> [&mut Vec<f64>; 9] {
        [
            &mut self.theta_n_rad,
            &mut self.phi_n_rad,
            &mut self.theta_p_rad,
            &mut self.phi_p_rad,
            &mut self.d_theta_rad,
            &mut self.d_phi_rad,
            &mut self.kf_d_theta_rad,
            &mut self.kf_d_phi_rad,
            &mut self.kryt1_cum,
        ]
    }

    /// Converts to a record batch of `schema` (from [`schema::criteria`]).
    pub fn to_batch(&self, schema: SchemaRef) -> Result<RecordBatch, FormatError> {
        let mut columns: Vec<ArrayRef> = vec![Arc::new(Int64Array::from(self.t_ns.clone()))];
        columns.extend(
            self.floats()
                .into_iter()
                .map(|v| Arc::new(Float64Array::from(v.clone())) as ArrayRef),
        );
        columns.push(Arc::new(BooleanArray::from(self.valid.clone())));
        batch(schema, columns)
    }

    /// Appends the rows of a batch.
    pub fn extend_from_batch(&mut self, b: &RecordBatch) -> Result<(), FormatError> {
        self.t_ns
            .extend(prim::<Int64Type>(b, schema::T_NS)?.values().iter());
        let valid = column(b, schema::VALID)?.as_boolean_opt().ok_or_else(|| {
            FormatError::Invalid(format!("column {:?} is not Boolean", schema::VALID))
        })?;
        self.valid.extend((0..valid.len()).map(|i| valid.value(i)));
        for (name, v) in schema::CRITERIA_FLOATS.iter().zip(self.floats_mut()) {
            v.extend(prim::<Float64Type>(b, name)?.values().iter());
        }
        Ok(())
    }
}

/// The values of a primitive column of a batch, borrowed (no copy): for readers that
/// gather a table's rows batch by batch.
pub fn values_of<'a, T: arrow::datatypes::ArrowPrimitiveType>(
    b: &'a RecordBatch,
    name: &str,
) -> Result<&'a [T::Native], FormatError> {
    Ok(prim::<T>(b, name)?.values())
}

/// Reads a `Float32` column of a batch.
pub fn f32_column(b: &RecordBatch, name: &str) -> Result<Vec<f32>, FormatError> {
    Ok(prim::<Float32Type>(b, name)?.values().to_vec())
}

/// A single-precision array of `values` (for the columns the schemas declare `Float32`).
pub fn f32_array(values: impl IntoIterator<Item = f64>) -> ArrayRef {
    Arc::new(arrow::array::Float32Array::from_iter_values(
        values.into_iter().map(|v| v as f32),
    ))
}

/// Reads an `Int64` column of a batch.
pub fn i64_column(b: &RecordBatch, name: &str) -> Result<Vec<i64>, FormatError> {
    Ok(prim::<Int64Type>(b, name)?.values().to_vec())
}

/// Reads a `UInt64` column of a batch.
pub fn u64_column(b: &RecordBatch, name: &str) -> Result<Vec<u64>, FormatError> {
    Ok(prim::<UInt64Type>(b, name)?.values().to_vec())
}

/// Reads a `UInt8` column of a batch.
pub fn u8_column(b: &RecordBatch, name: &str) -> Result<Vec<u8>, FormatError> {
    Ok(prim::<UInt8Type>(b, name)?.values().to_vec())
}

/// Reads a 3-vector column of a batch.
pub fn vec3_column(b: &RecordBatch, name: &str) -> Result<Vec<[f64; 3]>, FormatError> {
    vec3_values(b, name)
}

/// Builds a 3-vector array (for tables defined by the stages).
pub fn vec3_to_array(v: &[[f64; 3]]) -> ArrayRef {
    vec3_array(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A float column read in place gives what the copying reader gives, f32 widened
    /// exactly; another type is refused, naming it.
    #[test]
    fn float_values_in_place_are_the_copied_column() {
        use arrow::array::{Float32Array, Float64Array, Int64Array};
        use arrow::datatypes::{DataType, Field, Schema};
        let schema = Arc::new(Schema::new(vec![
            Field::new("a", DataType::Float64, false),
            Field::new("b", DataType::Float32, false),
            Field::new("n", DataType::Int64, false),
        ]));
        let b = RecordBatch::try_new(
            schema,
            vec![
                Arc::new(Float64Array::from(vec![0.1, -2.5e300, f64::NAN])),
                Arc::new(Float32Array::from(vec![0.1f32, -3.0e38, f32::MIN_POSITIVE])),
                Arc::new(Int64Array::from(vec![1, 2, 3])),
            ],
        )
        .unwrap();
        for name in ["a", "b"] {
            let v = float_values(&b, name).unwrap();
            let copied = f64_column(&b, name).unwrap();
            assert_eq!(copied.len(), 3);
            for (k, c) in copied.iter().enumerate() {
                assert_eq!(v.get(k).to_bits(), c.to_bits(), "{name}[{k}]");
            }
        }
        assert_eq!(float_values(&b, "b").unwrap().get(0), f64::from(0.1f32));
        let err = float_values(&b, "n").unwrap_err().to_string();
        assert!(err.contains("Int64"), "{err}");
        assert!(float_values(&b, "none").is_err());
    }

    #[test]
    fn the_criteria_table_reads_back_what_it_wrote() {
        let v = |k: f64| vec![k, -k, 0.5 * k];
        let table = CriteriaTable {
            t_ns: vec![1_000, 2_000, 3_000],
            theta_n_rad: v(1.0),
            phi_n_rad: v(2.0),
            theta_p_rad: v(3.0),
            phi_p_rad: v(4.0),
            d_theta_rad: v(5.0),
            d_phi_rad: v(6.0),
            kf_d_theta_rad: v(7.0),
            kf_d_phi_rad: v(8.0),
            kryt1_cum: v(9.0),
            valid: vec![true, false, true],
        };
        let batch = table.to_batch(schema::criteria()).unwrap();
        assert_eq!(batch.schema(), schema::criteria());
        let mut back = CriteriaTable::default();
        back.extend_from_batch(&batch).unwrap();
        back.extend_from_batch(&batch.slice(1, 2)).unwrap();
        let mut want = table.clone();
        for (w, t) in want.floats_mut().into_iter().zip(table.floats()) {
            w.extend_from_slice(&t[1..]);
        }
        want.t_ns.extend_from_slice(&table.t_ns[1..]);
        want.valid.extend_from_slice(&table.valid[1..]);
        assert_eq!(back, want);
        // A column of the wrong type is named.
        let e = CriteriaTable::default()
            .extend_from_batch(&batch.project(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"valid\""), "{e}");
    }
}
