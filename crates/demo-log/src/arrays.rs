//! Hand logs, hand frames and reports in the layout the Python binding hands to numpy and dicts:
//! flat row-major arrays with their shape ([`NdArray`]), checked here against the hand layout, so
//! the binding only copies numbers.

use crate::DemoError;
use crate::handlog::{HandFrame, HandLog, HandLogHeader};
use serde_json::Value;

/// An n-dimensional array: row-major `data` of shape `shape`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NdArray<T> {
    /// Length of each axis.
    pub shape: Vec<usize>,
    /// The elements, last axis fastest.
    pub data: Vec<T>,
}

impl<T> NdArray<T> {
    /// An array of `shape` from row-major `data`.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] when `data` does not hold `shape`'s product of elements.
    pub fn new(shape: Vec<usize>, data: Vec<T>) -> Result<NdArray<T>, DemoError> {
        if shape.iter().product::<usize>() != data.len() {
            return Err(DemoError::Invalid(format!("{} values do not fill shape {shape:?}", data.len())));
        }
        Ok(NdArray { shape, data })
    }

    /// A vector (one axis).
    pub fn vector(data: Vec<T>) -> NdArray<T> {
        NdArray { shape: vec![data.len()], data }
    }

    /// `rows × cols` from row-major `data` (`cols` 0: no rows).
    ///
    /// # Errors
    /// As [`NdArray::new`].
    pub fn matrix(data: Vec<T>, cols: usize) -> Result<NdArray<T>, DemoError> {
        let rows = data.len().checked_div(cols).unwrap_or(0);
        NdArray::new(vec![rows, cols], data)
    }
}

/// A shape as Python writes it: `(3,)`, `(2, 7)`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [a] => format!("({a},)"),
        _ => format!("({})", shape.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

impl<T> NdArray<T> {
    /// The elements, if the array has exactly `shape`.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] `"{what} must have shape (…), got (…)"` for any other shape.
    pub fn into_shape(self, shape: &[usize], what: &str) -> Result<Vec<T>, DemoError> {
        match self.shape == shape {
            true => Ok(self.data),
            false => Err(invalid(format!(
                "{what} must have shape {}, got {}",
                shape_text(shape),
                shape_text(&self.shape)
            ))),
        }
    }
}

impl<T> NdArray<T> {
    /// The elements of an `(n, cols)` array, any `n` (the first axis' length is taken as `n`).
    ///
    /// # Errors
    /// As [`NdArray::into_shape`].
    pub fn into_matrix(self, cols: usize, what: &str) -> Result<Vec<T>, DemoError> {
        let rows = self.shape.first().copied().unwrap_or(0);
        self.into_shape(&[rows, cols], what)
    }
}

impl<T: Copy> NdArray<T> {
    /// The rows of an `(n, K)` array as `[T; K]`; `None` for any other shape.
    pub fn rows<const K: usize>(&self) -> Option<Vec<[T; K]>> {
        match self.shape[..] {
            [_, k] if k == K => {
                Some(self.data.chunks_exact(K).map(|r| std::array::from_fn(|c| r[c])).collect())
            }
            _ => None,
        }
    }
}

/// A hand log's frames as arrays: `T` frames of `J` joints.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HandArrays {
    /// Frame times, `(T,)`.
    pub t: NdArray<f64>,
    /// Tracked flags, `(T,)`.
    pub tracked: NdArray<bool>,
    /// Joint positions, `(T, J, 3)`.
    pub joints: NdArray<f64>,
    /// Joint orientations `[x, y, z, w]`, `(T, J, 4)`; `None` unless every frame has them (and
    /// there is at least one frame).
    pub orientations: Option<NdArray<f64>>,
}

impl HandLog {
    /// The frames as arrays (see [`HandArrays`]).
    pub fn to_arrays(&self) -> HandArrays {
        let (n, j) = (self.frames.len(), self.header.layout.joint_count());
        let f = &self.frames;
        let joints = f.iter().flat_map(|f| f.joints.iter().flatten().copied()).collect();
        let o = f.iter().map(|f| f.orientations.as_ref()).collect::<Option<Vec<_>>>().filter(|_| n > 0);
        HandArrays {
            t: NdArray::vector(f.iter().map(|f| f.t).collect()),
            tracked: NdArray::vector(f.iter().map(|f| f.tracked).collect()),
            joints: NdArray { shape: vec![n, j, 3], data: joints },
            orientations: o.map(|o| NdArray {
                shape: vec![n, j, 4],
                data: o.into_iter().flat_map(|q| q.iter().flatten().copied()).collect(),
            }),
        }
    }

    /// A log from a header and its frames as arrays. The numbers are not checked here (writing
    /// does that: [`HandLog::validate`]).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] when the shapes are not `t (T,)`, `tracked (T,)`, `joints (T, J, 3)`
    /// and `orientations (T, J, 4)` for the header's layout of `J` joints.
    pub fn from_arrays(header: HandLogHeader, a: &HandArrays) -> Result<HandLog, DemoError> {
        let (n, jc) = (a.t.data.len(), header.layout.joint_count());
        if a.t.shape != [n] || a.tracked.shape != [n] || a.joints.shape != [n, jc, 3] {
            return Err(DemoError::Invalid(format!(
                "t (T,), tracked (T,), joints (T, {jc}, 3) expected for layout {}; got {:?}, {:?}, {:?}",
                header.layout.name(),
                a.t.shape,
                a.tracked.shape,
                a.joints.shape
            )));
        }
        if let Some(o) = &a.orientations
            && o.shape != [n, jc, 4]
        {
            return Err(DemoError::Invalid(format!("orientations must be (T, {jc}, 4), got {:?}", o.shape)));
        }
        let frames = (0..n)
            .map(|i| HandFrame {
                t: a.t.data[i],
                tracked: a.tracked.data[i],
                joints: chunks(&a.joints.data[i * jc * 3..(i + 1) * jc * 3]),
                orientations: a.orientations.as_ref().map(|o| chunks(&o.data[i * jc * 4..(i + 1) * jc * 4])),
            })
            .collect();
        Ok(HandLog { header, frames })
    }

    /// The header as the binding's dict: [`HandLogHeader::to_json`] with every optional key
    /// present (`null` when absent) and `joint_count`, the layout's number of joints.
    pub fn header_fields(&self) -> Value {
        let mut h = self.header.to_json();
        if let Value::Object(m) = &mut h {
            for k in ["task", "episode_seed", "source", "extra"] {
                m.entry(k).or_insert(Value::Null);
            }
            m.insert("joint_count".into(), Value::from(self.header.layout.joint_count()));
        }
        h
    }
}

fn chunks<const K: usize>(v: &[f64]) -> Vec<[f64; K]> {
    v.chunks_exact(K).map(|r| std::array::from_fn(|c| r[c])).collect()
}

impl HandFrame {
    /// One frame from joints `(J, 3)` and optional orientations `(J, 4)`.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for any other shapes.
    pub fn from_arrays(
        t: f64,
        tracked: bool,
        joints: &NdArray<f64>,
        orientations: Option<&NdArray<f64>>,
    ) -> Result<HandFrame, DemoError> {
        let joints = joints
            .rows::<3>()
            .ok_or_else(|| invalid(format!("joints must be (J, 3), got {:?}", joints.shape)))?;
        let orientations = match orientations {
            Some(o) if o.shape == [joints.len(), 4] => o.rows::<4>(),
            Some(o) => {
                return Err(invalid(format!(
                    "orientations must be ({}, 4), got {:?}",
                    joints.len(),
                    o.shape
                )));
            }
            None => None,
        };
        Ok(HandFrame { t, tracked, joints, orientations })
    }
}

fn invalid(msg: String) -> DemoError {
    DemoError::Invalid(msg)
}
