//! Point clouds: an organized or unorganized set of points with optional named per-point fields,
//! and their file formats.
//!
//! Coordinates are stored as `f32` because every sensor and every file format here delivers them
//! that way; keeping them in `f32` makes every read-write round trip bit-exact. Algorithms convert
//! to `f64` where they compute.

mod io;

pub use io::*;

/// The scalar type of an extra per-point field, as PCD (`TYPE`/`SIZE`) and PLY name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarKind {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

/// Values of one extra field for every point, `count` values per point, point-major.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldData {
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// A named per-point field beyond x, y, z (for example `rgba`, `label`, `intensity`, `normal_x`).
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: String,
    /// Values per point (PCD `COUNT`); 1 for plain scalars.
    pub count: usize,
    pub data: FieldData,
}

/// A point cloud. Organized clouds (`height > 1`) are row-major `width x height` images whose
/// missing returns are NaN points; unorganized clouds have `height == 1`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud {
    pub points: Vec<[f32; 3]>,
    pub width: usize,
    pub height: usize,
    pub fields: Vec<Field>,
}
