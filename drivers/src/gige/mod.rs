//! GigE Vision line-profile cameras (SICK Ranger3 and Ruler3000 class, GenICam): what a frame
//! of such a camera means, as pure functions, and (with the `gige` feature) the camera itself
//! through aravis (the `camera` module).
//!
//! In its 3D mode (`DeviceScanType = Linescan3D`) the camera sends each GigE Vision frame as a
//! block of profiles: one image row a profile, `Height` rows a block, `Width` columns, each
//! pixel the range of its column (`Coord3D_C16`, `Coord3D_C12p` or `Mono16`). The range turns
//! into sub-pixel sensor rows (the unit of the calibration chain, `Profile::rows`) by
//! `Scan3dCoordinateScale` and `Scan3dCoordinateOffset`; `Scan3dInvalidDataValue` marks a column
//! without a return. Each row's exposure time is the block's timestamp plus the row's index over
//! the line rate ([`RowTiming`]). `drivers/README.md` says which of this is checked against
//! aravis's camera emulator and which only against the manuals.

#[cfg(feature = "gige")]
pub mod camera;

use crate::profile::Profile;

/// A feature value to set, by its GenICam type.
#[derive(Clone, Debug, PartialEq)]
pub enum FeatureValue {
    Bool(bool),
    Int(i64),
    Float(f64),
    /// An enumeration entry or a string.
    Str(String),
}

impl std::fmt::Display for FeatureValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FeatureValue::Bool(b) => write!(f, "{b}"),
            FeatureValue::Int(i) => write!(f, "{i}"),
            FeatureValue::Float(x) => write!(f, "{x}"),
            FeatureValue::Str(s) => write!(f, "{s:?}"),
        }
    }
}

/// GenICam PFNC codes of the range formats a block may carry.
pub const MONO16: u32 = 0x0110_0007;
pub const COORD3D_C16: u32 = 0x0110_00B8;
pub const COORD3D_C12P: u32 = 0x010C_00DA;

/// How the pixels of a block hold their range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangePixel {
    /// 16 bits a pixel, little-endian (`Coord3D_C16`, `Mono16`).
    U16,
    /// 12 bits a pixel, two pixels in three bytes, least significant bits first, packed across
    /// the rows of the block (`Coord3D_C12p`).
    U12Packed,
}

impl RangePixel {
    /// The format of a PFNC code, `None` for a format that is no range.
    pub fn from_pfnc(code: u32) -> Option<RangePixel> {
        match code {
            MONO16 | COORD3D_C16 => Some(RangePixel::U16),
            COORD3D_C12P => Some(RangePixel::U12Packed),
            _ => None,
        }
    }

    /// The format of a GenICam `PixelFormat` name.
    pub fn from_name(name: &str) -> Option<RangePixel> {
        match name {
            "Mono16" | "Coord3D_C16" => Some(RangePixel::U16),
            "Coord3D_C12p" => Some(RangePixel::U12Packed),
            _ => None,
        }
    }

    /// Bytes of `pixels` pixels (`None` past what memory holds).
    pub fn bytes(self, pixels: usize) -> Option<usize> {
        match self {
            RangePixel::U16 => pixels.checked_mul(2),
            RangePixel::U12Packed => Some(pixels.checked_mul(12)?.div_ceil(8)),
        }
    }
}

/// What turns a pixel into a sub-pixel row: `row = pixel * scale + offset`, no return where the
/// pixel equals `invalid`, as fixed point with `fraction_bits` (the calibration's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeEncoding {
    pub pixel: RangePixel,
    pub scale: f64,
    pub offset: f64,
    /// `Scan3dInvalidDataValue` when `Scan3dInvalidDataFlag` is set.
    pub invalid: Option<f64>,
    pub fraction_bits: u8,
}

/// Which row of a block the block's timestamp is the exposure of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StampedRow {
    First,
    Last,
}

/// When each row of a block was exposed, on the camera's clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowTiming {
    /// The block's timestamp (ns, camera clock).
    pub block_ns: u64,
    /// 1 / `AcquisitionLineRate` (ns).
    pub line_period_ns: f64,
    pub stamped: StampedRow,
}

impl RowTiming {
    /// Exposure of row `i` of `height` (ns, camera clock).
    pub fn row_ns(&self, i: usize, height: usize) -> u64 {
        let steps = match self.stamped {
            StampedRow::First => i as f64,
            StampedRow::Last => i as f64 - (height.saturating_sub(1)) as f64,
        };
        // In integer nanoseconds: a PTP-synchronised stamp (~1.7e18 ns) is not exact in f64.
        let shift = (steps * self.line_period_ns).round() as i64;
        self.block_ns.saturating_add_signed(shift)
    }
}

/// Why a block cannot be decoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BlockError {
    #[error("block of {got} bytes, {width} x {height} {pixel:?} needs {need}")]
    Size {
        got: usize,
        need: usize,
        width: usize,
        height: usize,
        pixel: RangePixel,
    },
    #[error("block of {width} x {height}: a profile needs 1 to 65535 columns")]
    Shape { width: usize, height: usize },
    #[error("coordinate scale {0}: not a positive finite number")]
    Scale(f64),
    #[error("{0} fraction bits: give 0 to 15")]
    FractionBits(u8),
}

/// One pixel's raw value.
fn pixel(bytes: &[u8], pixel: RangePixel, i: usize) -> u16 {
    match pixel {
        RangePixel::U16 => u16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]),
        RangePixel::U12Packed => {
            let k = 3 * (i / 2);
            if i.is_multiple_of(2) {
                u16::from(bytes[k]) | (u16::from(bytes[k + 1] & 0x0f) << 8)
            } else {
                u16::from(bytes[k + 1] >> 4) | (u16::from(bytes[k + 2]) << 4)
            }
        }
    }
}

/// The profiles of one block, sequence numbers from `first_seq` on. Rows are the block's image
/// rows in order; a pixel outside what the fixed point holds (at or below zero, or beyond its
/// range) is no return, as an invalid one is.
pub fn decode_block(
    bytes: &[u8],
    width: usize,
    height: usize,
    enc: &RangeEncoding,
    timing: &RowTiming,
    first_seq: u32,
) -> Result<Vec<Profile>, BlockError> {
    if width == 0 || width > usize::from(u16::MAX) || height == 0 {
        return Err(BlockError::Shape { width, height });
    }
    if !(enc.scale.is_finite() && enc.scale > 0.0) {
        return Err(BlockError::Scale(enc.scale));
    }
    if enc.fraction_bits > 15 {
        return Err(BlockError::FractionBits(enc.fraction_bits));
    }
    let need = width
        .checked_mul(height)
        .and_then(|n| enc.pixel.bytes(n))
        .unwrap_or(usize::MAX);
    // A camera may pad a block; it may not cut it short.
    if bytes.len() < need {
        return Err(BlockError::Size {
            got: bytes.len(),
            need,
            width,
            height,
            pixel: enc.pixel,
        });
    }
    let unit = f64::from(1u32 << enc.fraction_bits);
    let offset = if enc.offset.is_finite() { enc.offset } else { 0.0 };
    let mut out = Vec::with_capacity(height);
    for r in 0..height {
        let rows = (0..width)
            .map(|c| {
                let raw = pixel(bytes, enc.pixel, r * width + c);
                if enc.invalid.is_some_and(|v| f64::from(raw) == v) {
                    return 0;
                }
                let fixed = ((f64::from(raw) * enc.scale + offset) * unit).round();
                if fixed >= 1.0 && fixed <= f64::from(u16::MAX) {
                    fixed as u16
                } else {
                    0
                }
            })
            .collect();
        out.push(Profile {
            seq: first_seq.wrapping_add(r as u32),
            timestamp_ns: timing.row_ns(r, height),
            fraction_bits: enc.fraction_bits,
            rows,
            intensity: None,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c16(values: &[u16]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    const TIMING: RowTiming = RowTiming {
        block_ns: 1_000_000,
        line_period_ns: 250_000.0,
        stamped: StampedRow::First,
    };

    #[test]
    fn rows_become_profiles_with_scale_offset_and_invalid_value() {
        // 3 columns x 2 rows; pixels in 1/16 rows, shifted by 2 rows; 0 = no return.
        let bytes = c16(&[160, 0, 320, 16, 65535, 48]);
        let enc = RangeEncoding {
            pixel: RangePixel::U16,
            scale: 1.0 / 16.0,
            offset: 2.0,
            invalid: Some(0.0),
            fraction_bits: 4,
        };
        let p = decode_block(&bytes, 3, 2, &enc, &TIMING, 7).unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].rows, [(10 + 2) * 16, 0, (20 + 2) * 16]);
        assert_eq!(p[0].row_px(0), Some(12.0));
        // 65535 / 16 + 2 rows is beyond what 4 fraction bits in 16 bits hold: no return.
        assert_eq!(p[1].rows, [3 * 16, 0, 5 * 16]);
        assert_eq!((p[0].seq, p[1].seq), (7, 8));
        assert_eq!((p[0].timestamp_ns, p[1].timestamp_ns), (1_000_000, 1_250_000));
        assert!(p.iter().all(|p| p.fraction_bits == 4 && p.intensity.is_none()));
    }

    #[test]
    fn the_block_stamp_may_be_the_last_rows() {
        let t = RowTiming {
            stamped: StampedRow::Last,
            ..TIMING
        };
        assert_eq!(t.row_ns(3, 4), 1_000_000);
        assert_eq!(t.row_ns(0, 4), 250_000);
        // Never before the clock's zero.
        assert_eq!(t.row_ns(0, 100), 0);
    }

    #[test]
    fn twelve_bit_packed_pixels() {
        // 0xABC, 0x123, 0x456 and 0x789 on the next row: [BC, 3A, 12] [56, 94, 78].
        let bytes = [0xBC, 0x3A, 0x12, 0x56, 0x94, 0x78];
        let enc = RangeEncoding {
            pixel: RangePixel::U12Packed,
            scale: 1.0,
            offset: 0.0,
            invalid: None,
            fraction_bits: 0,
        };
        assert_eq!(RangePixel::U12Packed.bytes(3), Some(5));
        let p = decode_block(&bytes, 2, 2, &enc, &TIMING, 0).unwrap();
        assert_eq!(p[0].rows, [0xABC, 0x123]);
        assert_eq!(p[1].rows, [0x456, 0x789]);
        assert!(decode_block(&bytes[..5], 2, 2, &enc, &TIMING, 0).is_err());
    }

    #[test]
    fn short_blocks_and_absurd_encodings_are_errors_not_panics() {
        let enc = RangeEncoding {
            pixel: RangePixel::U16,
            scale: 1.0,
            offset: 0.0,
            invalid: None,
            fraction_bits: 4,
        };
        let e = decode_block(&[0; 11], 3, 2, &enc, &TIMING, 0).unwrap_err();
        assert!(e.to_string().contains("needs 12"), "{e}");
        assert!(decode_block(&[], 0, 2, &enc, &TIMING, 0).is_err());
        assert!(decode_block(&[0; 4], 2, 1, &RangeEncoding { scale: f64::NAN, ..enc }, &TIMING, 0).is_err());
        assert!(decode_block(&[0; 4], 2, 1, &RangeEncoding { scale: 0.0, ..enc }, &TIMING, 0).is_err());
        assert!(
            decode_block(
                &[0; 4],
                2,
                1,
                &RangeEncoding {
                    fraction_bits: 16,
                    ..enc
                },
                &TIMING,
                0
            )
            .is_err()
        );
        // A huge claimed size cannot overflow.
        assert!(decode_block(&[0; 4], 60_000, usize::MAX / 2, &enc, &TIMING, 0).is_err());
        // Padding after the rows is ignored.
        assert_eq!(
            decode_block(&[1, 0, 2, 0, 9, 9], 2, 1, &enc, &TIMING, 0).unwrap()[0].rows,
            [16, 32]
        );
    }

    #[test]
    fn pixel_formats_by_code_and_name() {
        assert_eq!(RangePixel::from_pfnc(COORD3D_C16), Some(RangePixel::U16));
        assert_eq!(RangePixel::from_pfnc(MONO16), Some(RangePixel::U16));
        assert_eq!(RangePixel::from_pfnc(COORD3D_C12P), Some(RangePixel::U12Packed));
        assert_eq!(RangePixel::from_pfnc(0x0108_0001), None);
        assert_eq!(RangePixel::from_name("Coord3D_C12p"), Some(RangePixel::U12Packed));
        assert_eq!(RangePixel::from_name("Mono8"), None);
    }
}
