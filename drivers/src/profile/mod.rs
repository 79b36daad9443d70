//! Laser profile streams (IVP/SICK Ranger style): our own documented SQPF frame.
//!
//! The 2007 sensor's transport is not public, so the sensor side (or its bridge) emits SQPF
//! frames; see `frame` for the byte layout and the crate README for the rationale.
//!
//! - [`frame`]: [`Profile`], [`encode_profile`], the incremental [`ProfileDecoder`].
//! - [`crc`]: the CRC-32/IEEE checksum.
//! - [`seq`]: [`SequenceTracker`] for drops, duplicates and reordering.

pub mod crc;
pub mod frame;
pub mod seq;

pub use crc::{Crc32, crc32};
pub use frame::{Profile, ProfileDecoder, ProfileDecoderStats, ProfileError, encode_profile};
pub use seq::{SeqCounts, SeqEvent, SequenceTracker};
