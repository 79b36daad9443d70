//! LZF compression as in Marc Lehmann's liblzf, which PCL uses for `binary_compressed` PCD data.
//!
//! The stream is a sequence of instructions, each starting with a control byte `ctrl`:
//! - `ctrl < 32`: a literal run; the next `ctrl + 1` bytes are copied to the output.
//! - otherwise a back-reference: `len = ctrl >> 5` (if 7, an extra byte is added to it), then one
//!   more byte; the match copies `len + 2` bytes starting `((ctrl & 0x1f) << 8 | byte) + 1` bytes
//!   back in the output (it may overlap the bytes it produces).
//!
//! So offsets reach back at most 8192 bytes and a match is at most 264 bytes long.

use super::CloudError;

/// Longest literal run of one instruction.
const MAX_LIT: usize = 32;
/// Farthest a back-reference reaches (offset - 1 is stored in 13 bits).
const MAX_OFF: usize = 1 << 13;
/// Longest match: stored length 7 + 255, plus the implicit 2.
const MAX_REF: usize = 264;
/// Largest output per input byte: a 3-byte back-reference producing `MAX_REF` bytes. Used to
/// reject declared sizes no input of this length can produce before allocating them.
pub const MAX_EXPANSION: usize = MAX_REF / 3;

const HASH_LOG: u32 = 14;

/// Compresses `input`. The result decompresses with any LZF decoder (liblzf `lzf_decompress`,
/// PCL). Incompressible data grows by at most one byte per 32 plus one.
pub fn compress(input: &[u8]) -> Vec<u8> {
    let n = input.len();
    let mut out = Vec::with_capacity(n + n / MAX_LIT + 1);
    // Most recent position + 1 of each 3-byte hash; 0 means none.
    let mut table = vec![0usize; 1 << HASH_LOG];
    let hash = |p: usize| -> usize {
        let v = u32::from(input[p]) << 16 | u32::from(input[p + 1]) << 8 | u32::from(input[p + 2]);
        (v.wrapping_mul(0x9E37_79B1) >> (32 - HASH_LOG)) as usize
    };

    // The control byte of the open literal run is at `ctrl`, followed by `lit` literals.
    let mut ctrl = out.len();
    out.push(0);
    let mut lit = 0usize;
    let mut ip = 0usize;

    while ip + 2 < n {
        let h = hash(ip);
        let candidate = table[h];
        table[h] = ip + 1;
        if let Some(r) = candidate.checked_sub(1) {
            let off = ip - r - 1;
            if off < MAX_OFF && input[r..r + 3] == input[ip..ip + 3] {
                let max_len = (n - ip).min(MAX_REF);
                let mut len = 3;
                while len < max_len && input[r + len] == input[ip + len] {
                    len += 1;
                }
                // Close the literal run, or drop its control byte if the run is empty.
                if lit > 0 {
                    out[ctrl] = (lit - 1) as u8;
                } else {
                    out.pop();
                }
                let stored = len - 2;
                let off_hi = (off >> 8) as u8;
                if stored < 7 {
                    out.push(off_hi | (stored as u8) << 5);
                } else {
                    out.push(off_hi | 7 << 5);
                    out.push((stored - 7) as u8);
                }
                out.push(off as u8);
                // Index the positions inside the match too: better ratio for little time.
                for p in ip + 1..(ip + len).min(n - 2) {
                    table[hash(p)] = p + 1;
                }
                ip += len;
                ctrl = out.len();
                out.push(0);
                lit = 0;
                continue;
            }
        }
        push_literal(&mut out, &mut ctrl, &mut lit, input[ip]);
        ip += 1;
    }
    while ip < n {
        push_literal(&mut out, &mut ctrl, &mut lit, input[ip]);
        ip += 1;
    }
    if lit > 0 {
        out[ctrl] = (lit - 1) as u8;
    } else {
        out.pop();
    }
    out
}

fn push_literal(out: &mut Vec<u8>, ctrl: &mut usize, lit: &mut usize, byte: u8) {
    out.push(byte);
    *lit += 1;
    if *lit == MAX_LIT {
        out[*ctrl] = (MAX_LIT - 1) as u8;
        *ctrl = out.len();
        out.push(0);
        *lit = 0;
    }
}

/// Decompresses `input`, which must produce exactly `expected_len` bytes.
///
/// Errors ([`CloudError::Lzf`], offsets relative to `input`) on a truncated instruction, a
/// back-reference before the start of the output, output beyond `expected_len`, or a short
/// result. An `expected_len` larger than `input` could possibly produce is rejected before
/// anything is allocated.
pub fn decompress(input: &[u8], expected_len: usize) -> Result<Vec<u8>, CloudError> {
    let err = |offset, msg| Err(CloudError::Lzf { offset, msg });
    if expected_len > input.len().saturating_mul(MAX_EXPANSION) {
        return err(0, "declared uncompressed size is larger than the data can expand to");
    }
    // The output is written in place, with room for a whole block past its end: a run is copied
    // a fixed 16 or 32 bytes at a time (a few moves, where a call to memcpy per run of a few
    // bytes cost more than the data), and what lands past the run is overwritten by the next.
    let mut out = vec![0u8; expected_len + MAX_LIT];
    let mut op = 0usize;
    let mut ip = 0usize;
    while let Some(&ctrl) = input.get(ip) {
        let start = ip;
        ip += 1;
        let ctrl = usize::from(ctrl);
        if ctrl < 32 {
            let len = ctrl + 1;
            if ip + len > input.len() {
                return err(start, "literal run past the end of the data");
            }
            if op + len > expected_len {
                return err(start, "output longer than the declared size");
            }
            if ip + MAX_LIT <= input.len() {
                // SAFETY: `ip + MAX_LIT <= input.len()` just above, and `op + MAX_LIT <=
                // expected_len + MAX_LIT = out.len()` as `op + len <= expected_len`; two
                // buffers never overlap.
                unsafe { std::ptr::copy_nonoverlapping(input.as_ptr().add(ip), out.as_mut_ptr().add(op), MAX_LIT) };
            } else {
                out[op..op + len].copy_from_slice(&input[ip..ip + len]);
            }
            ip += len;
            op += len;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                let Some(&extra) = input.get(ip) else {
                    return err(start, "back-reference past the end of the data");
                };
                len += usize::from(extra);
                ip += 1;
            }
            let Some(&lo) = input.get(ip) else {
                return err(start, "back-reference past the end of the data");
            };
            ip += 1;
            len += 2;
            let back = ((ctrl & 0x1f) << 8 | usize::from(lo)) + 1;
            if back > op {
                return err(start, "back-reference before the start of the output");
            }
            if op + len > expected_len {
                return err(start, "output longer than the declared size");
            }
            copy_back(&mut out, op, back, len);
            op += len;
        }
    }
    if op != expected_len {
        return err(
            input.len(),
            "data ends before the declared uncompressed size is reached",
        );
    }
    out.truncate(expected_len);
    Ok(out)
}

/// LZF's back-reference: the `len` bytes from `back` bytes behind `op` copied to `op` in `out`,
/// as if byte by byte (so an overlapping run repeats its last `back` bytes), 16 bytes at a time:
/// up to 15 bytes past `op + len` are written over, which the next instruction overwrites.
#[inline(always)]
fn copy_back(out: &mut [u8], op: usize, back: usize, len: usize) {
    // Every copy below writes within `op..op + len + 15` and reads before what it writes: the
    // caller checked `op + len <= expected_len`, and `out` has MAX_LIT bytes to spare, so the
    // copies are made through a pointer, without a bounds check per block or byte.
    assert!((1..=op).contains(&back) && op + len + 16 <= out.len());
    let from = op - back;
    let base = out.as_mut_ptr();
    if back >= 16 {
        // Each block lies wholly before the one it is copied to.
        let mut k = 0;
        while k < len {
            // SAFETY: both blocks lie within `out` (asserted above) and are `back >= 16` bytes
            // apart, so they do not overlap.
            unsafe { std::ptr::copy_nonoverlapping(base.add(from + k), base.add(op + k), 16) };
            k += 16;
        }
    } else {
        // The source overlaps the bytes being produced: a run repeating the last `back` bytes.
        // Its first `period` bytes (the smallest multiple of `back` of at least a block) byte by
        // byte, as the format defines it; from there the run repeats what lies `period` bytes
        // back, a whole block before.
        let period = back * 16usize.div_ceil(back);
        let head = len.min(period);
        for k in 0..head {
            // SAFETY: `from + k < op + k < op + len`, within `out`.
            unsafe { *base.add(op + k) = *base.add(from + k) };
        }
        let mut k = head;
        while k < len {
            // SAFETY: within `out` (asserted above); `period >= 16` bytes apart.
            unsafe { std::ptr::copy_nonoverlapping(base.add(op + k - period), base.add(op + k), 16) };
            k += 16;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn round_trip(data: &[u8]) -> usize {
        let c = compress(data);
        assert_eq!(decompress(&c, data.len()).unwrap(), data);
        c.len()
    }

    #[test]
    fn round_trips() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        assert_eq!(round_trip(&[]), 0);
        round_trip(&[1]);
        round_trip(&[1, 2]);
        round_trip(&[1, 2, 3]);
        let random: Vec<u8> = (0..100_000).map(|_| rng.random()).collect();
        let c = round_trip(&random);
        assert!(c <= random.len() + random.len() / 32 + 1);
        let zeros = vec![0u8; 100_000];
        assert!(round_trip(&zeros) < 1300);
        let pattern: Vec<u8> = (0..50_000u32).flat_map(|i| (i % 977).to_le_bytes()).collect();
        assert!(round_trip(&pattern) < pattern.len() / 2);
        // Lengths around the literal-run and match limits.
        for n in [31, 32, 33, 63, 64, 65, 263, 264, 265, 266, 8193, 8194] {
            round_trip(&vec![9u8; n]);
            let r: Vec<u8> = (0..n).map(|_| rng.random_range(0..4)).collect();
            round_trip(&r);
        }
    }

    /// The format's definition, a byte at a time.
    fn reference(input: &[u8]) -> Vec<u8> {
        let (mut out, mut ip) = (Vec::new(), 0);
        while ip < input.len() {
            let ctrl = usize::from(input[ip]);
            ip += 1;
            if ctrl < 32 {
                out.extend_from_slice(&input[ip..ip + ctrl + 1]);
                ip += ctrl + 1;
            } else {
                let mut len = ctrl >> 5;
                if len == 7 {
                    len += usize::from(input[ip]);
                    ip += 1;
                }
                let from = out.len() - (((ctrl & 0x1f) << 8 | usize::from(input[ip])) + 1);
                ip += 1;
                for k in 0..len + 2 {
                    out.push(out[from + k]);
                }
            }
        }
        out
    }

    /// Streams no compressor of ours would write: every run length and distance, short ones
    /// overlapping what they produce, in every position against the end of the data.
    #[test]
    fn every_distance_and_length_decodes_as_the_format_defines() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for _ in 0..3000 {
            let mut stream = Vec::new();
            let mut produced = 0usize;
            for _ in 0..rng.random_range(1..12) {
                if produced == 0 || rng.random_bool(0.3) {
                    let n = rng.random_range(1..=32usize);
                    stream.push((n - 1) as u8);
                    stream.extend((0..n).map(|_| rng.random::<u8>()));
                    produced += n;
                } else {
                    let back = rng.random_range(1..=produced.min(40));
                    let len = rng.random_range(3..=264usize);
                    let stored = len - 2;
                    let off = back - 1;
                    if stored < 7 {
                        stream.push((stored << 5 | off >> 8) as u8);
                    } else {
                        stream.push((7 << 5 | off >> 8) as u8);
                        stream.push((stored - 7) as u8);
                    }
                    stream.push(off as u8);
                    produced += len;
                }
            }
            let want = reference(&stream);
            assert_eq!(decompress(&stream, want.len()).unwrap(), want);
        }
    }

    #[test]
    fn known_stream() {
        // "abcabcabc": 3 literals, then a back-reference of 6 bytes at offset 3.
        let stream = [2, b'a', b'b', b'c', (4 << 5), 2];
        assert_eq!(decompress(&stream, 9).unwrap(), b"abcabcabc");
    }

    #[test]
    fn corrupt_input_is_an_error() {
        let msg = |r: Result<Vec<u8>, CloudError>| r.unwrap_err().to_string();
        assert!(msg(decompress(&[5, 1, 2], 6)).contains("byte 0"));
        assert!(msg(decompress(&[0, 7, 0x20, 5], 4)).contains("byte 2: back-reference before"));
        assert!(msg(decompress(&[0, 7, 0xe0], 100)).contains("byte 2"));
        assert!(msg(decompress(&[1, 1, 2], 1)).contains("longer than"));
        assert!(msg(decompress(&[0, 1], 2)).contains("ends before"));
        assert!(msg(decompress(&[0, 1], 1 << 40)).contains("larger than"));
    }
}
