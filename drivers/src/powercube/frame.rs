//! PowerCube RS-232 telegram framing: escaping, TelID, checksum, and an incremental decoder.
//!
//! Over 600 lines on purpose: the datasheet's telegram layout, the encoder, the incremental
//! decoder and their byte-literal tests belong together; split, the layout table would be read in
//! one file and checked in another.
//!
//! ```text
//! on the wire:   STX | escaped( TelID0 TelID1 D0 .. Dn-1 BCC ) | ETX
//!
//!  byte     bits         meaning
//!  STX      0000 0010    0x02, start of telegram (never escaped: marks a frame start, always)
//!  TelID0   0000 01ii    host -> module, ii = module id bits 4..3      (0x04 | id >> 3)
//!           0000 10ii    module -> host                                (0x08 | id >> 3)
//!  TelID1   iiil llll    iii = module id bits 2..0, lllll = n, the number of data bytes (0..=8)
//!  D0       cccc cccc    command byte (0x00 RESET, 0x0A GET_EXT, ...); D1.. its arguments
//!  BCC      bbbb bbbb    checksum over TelID and data, see `schunk_bcc` / `player_bcc`
//!  ETX      0000 0011    0x03, end of telegram
//!
//!  escaping (TelID, data and BCC alike): 0x02 -> 10 82, 0x03 -> 10 83, 0x10 -> 10 90
//! ```
//!
//! Module id of a telegram: `((TelID0 & 0x03) << 3) | (TelID1 >> 5)`.

use std::collections::VecDeque;
use std::fmt;

/// Start of telegram.
pub const STX: u8 = 0x02;
/// End of telegram.
pub const ETX: u8 = 0x03;
/// Escape prefix (DLE): the next byte is the escaped byte plus [`ESCAPE_OFFSET`].
pub const DLE: u8 = 0x10;
/// What an escaped byte has added to it on the wire.
pub const ESCAPE_OFFSET: u8 = 0x80;
/// Most data bytes one telegram carries (the CAN heritage of the protocol).
pub const MAX_DATA_LEN: usize = 8;
/// TelID (2) + data (<= 8) + BCC (1), unescaped.
const MAX_BODY_LEN: usize = 2 + MAX_DATA_LEN + 1;

/// Address of one module on the serial line: 5 bits on the wire, 1..=31 in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ModuleId(u8);

impl ModuleId {
    /// A module id in 1..=31; `None` outside (0 is not a module, and the wire field has 5 bits).
    pub const fn new(id: u8) -> Option<Self> {
        if id >= 1 && id <= 31 { Some(Self(id)) } else { None }
    }

    /// The id as a number.
    pub const fn get(self) -> u8 {
        self.0
    }
}

impl fmt::Display for ModuleId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "module {}", self.0)
    }
}

/// Who sent a telegram, from the high bits of TelID0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Host to module (TelID0 = 0x04 | id >> 3): a request.
    ToModule,
    /// Module to host (TelID0 = 0x08 | id >> 3): a reply.
    ToHost,
}

impl Direction {
    const fn telid0_base(self) -> u8 {
        match self {
            Direction::ToModule => 0x04,
            Direction::ToHost => 0x08,
        }
    }
}

/// Up to [`MAX_DATA_LEN`] data bytes, held inline (a telegram never needs an allocation).
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Payload {
    buf: [u8; MAX_DATA_LEN],
    len: u8,
}

impl Payload {
    /// Copies `data`; fails if it is longer than [`MAX_DATA_LEN`].
    pub fn new(data: &[u8]) -> Result<Self, FrameError> {
        let mut p = Self::default();
        for &b in data {
            if !p.push(b) {
                return Err(FrameError::DataTooLong { len: data.len() });
            }
        }
        Ok(p)
    }

    /// Appends a byte; `false` (and nothing appended) when full.
    pub fn push(&mut self, byte: u8) -> bool {
        match self.buf.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = byte;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Appends bytes; `false` (and nothing appended) if they do not all fit.
    pub fn extend(&mut self, bytes: &[u8]) -> bool {
        if usize::from(self.len) + bytes.len() > MAX_DATA_LEN {
            return false;
        }
        bytes.iter().all(|&b| self.push(b))
    }

    /// The data bytes.
    pub fn as_slice(&self) -> &[u8] {
        self.buf.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Number of data bytes.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// No data bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl fmt::Debug for Payload {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Payload[")?;
        for (i, b) in self.as_slice().iter().enumerate() {
            if i > 0 {
                write!(f, " ")?;
            }
            write!(f, "{b:02X}")?;
        }
        write!(f, "]")
    }
}

/// One unescaped telegram.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Frame {
    pub direction: Direction,
    pub module: ModuleId,
    pub data: Payload,
}

impl Frame {
    /// A host-to-module telegram.
    pub fn request(module: ModuleId, data: Payload) -> Self {
        Self {
            direction: Direction::ToModule,
            module,
            data,
        }
    }

    /// A module-to-host telegram.
    pub fn reply(module: ModuleId, data: Payload) -> Self {
        Self {
            direction: Direction::ToHost,
            module,
            data,
        }
    }

    /// The two TelID bytes, unescaped.
    pub fn telid(&self) -> [u8; 2] {
        let id = self.module.get();
        // len <= 8 by construction of Payload, so it fits the 5-bit field.
        let len = self.data.len() as u8;
        [self.direction.telid0_base() | (id >> 3), ((id << 5) & 0xE0) | len]
    }

    /// The telegram as sent on the wire: STX, escaped TelID/data/Schunk BCC, ETX.
    ///
    /// We always send the Schunk checksum: it is what Schunk's own library sends, and
    /// PROTOCOLS.md leaves open which form the modules check.
    pub fn encode(&self) -> Vec<u8> {
        let telid = self.telid();
        let bcc = schunk_bcc(telid, self.data.as_slice());
        // Worst case every body byte is escaped.
        let mut out = Vec::with_capacity(2 + 2 * MAX_BODY_LEN);
        out.push(STX);
        for &b in telid.iter().chain(self.data.as_slice()).chain(std::iter::once(&bcc)) {
            if matches!(b, STX | ETX | DLE) {
                out.push(DLE);
                out.push(b.wrapping_add(ESCAPE_OFFSET));
            } else {
                out.push(b);
            }
        }
        out.push(ETX);
        out
    }
}

/// Encodes a host-to-module telegram. Fails only if `data` is longer than 8 bytes.
pub fn encode_request(module: ModuleId, data: &[u8]) -> Result<Vec<u8>, FrameError> {
    Ok(Frame::request(module, Payload::new(data)?).encode())
}

/// Encodes a module-to-host telegram (what a mock module sends). Fails only if `data` > 8 bytes.
pub fn encode_reply(module: ModuleId, data: &[u8]) -> Result<Vec<u8>, FrameError> {
    Ok(Frame::reply(module, Payload::new(data)?).encode())
}

/// Schunk's checksum (libm5api): `s = TelID0 + TelID1 + sum(data)` as u16, `BCC = (s + (s >> 8)) as u8`,
/// i.e. the 8-bit sum with the carries folded back in once.
pub fn schunk_bcc(telid: [u8; 2], data: &[u8]) -> u8 {
    let s = telid
        .iter()
        .chain(data)
        .fold(0u16, |acc, &b| acc.wrapping_add(u16::from(b)));
    (s.wrapping_add(s >> 8)) as u8
}

/// The CARMEN/Player checksum, as Player's `amtecpowercube` `SendCommand` computes it.
///
/// Player starts an `unsigned char` accumulator at the *module id* it is addressing (the plain
/// number 1..=31, not either TelID byte), adds the data bytes, then adds `bcc >> 8`, which is
/// always 0 for an 8-bit accumulator. So the form is `(module_id + sum(data)) as u8`. Player never
/// checks a received BCC, so nothing says modules reply with this form; when decoding we take the
/// "TelID-derived id" to be the 5-bit module id decoded from the TelID
/// (`((TelID0 & 3) << 3) | (TelID1 >> 5)`), for either direction.
pub fn player_bcc(module: ModuleId, data: &[u8]) -> u8 {
    data.iter().fold(module.get(), |acc, &b| acc.wrapping_add(b))
}

/// Which checksum form a received telegram carried.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ChecksumForm {
    /// [`schunk_bcc`] (checked first: when both forms agree the telegram counts as Schunk).
    Schunk,
    /// [`player_bcc`].
    Player,
}

/// What is wrong with a telegram. The decoder reports it and resynchronises on the next STX.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    #[error("bad checksum: received {received:#04x}, expected {schunk:#04x} (Schunk) or {player:#04x} (Player)")]
    BadChecksum { received: u8, schunk: u8, player: u8 },
    #[error("length field says {declared} data bytes, telegram carries {actual}")]
    LengthMismatch { declared: u8, actual: usize },
    #[error("{len} data bytes, more than the 8 a telegram can carry")]
    DataTooLong { len: usize },
    #[error("telegram body longer than {MAX_BODY_LEN} bytes without ETX")]
    BodyTooLong,
    #[error("telegram body of {len} bytes is too short for TelID and BCC")]
    TooShort { len: usize },
    #[error("bad escape: DLE followed by {0:#04x}")]
    BadEscape(u8),
    #[error("bad TelID {0:#04x} {1:#04x} (unknown direction or module id 0)")]
    BadTelId(u8, u8),
    #[error("telegram cut short by a new STX after {body_len} body bytes")]
    Interrupted { body_len: usize },
}

impl FrameError {
    /// A checksum fault rather than a malformed telegram.
    pub fn is_checksum(&self) -> bool {
        matches!(self, FrameError::BadChecksum { .. })
    }
}

/// Validates an unescaped body `TelID0 TelID1 data.. BCC` into a frame.
fn parse_body(body: &[u8]) -> Result<(Frame, ChecksumForm), FrameError> {
    let [t0, t1, rest @ ..] = body else {
        return Err(FrameError::TooShort { len: body.len() });
    };
    let [data @ .., bcc] = rest else {
        return Err(FrameError::TooShort { len: body.len() });
    };
    let direction = match t0 & 0xFC {
        0x04 => Direction::ToModule,
        0x08 => Direction::ToHost,
        _ => return Err(FrameError::BadTelId(*t0, *t1)),
    };
    let module = ModuleId::new(((t0 & 0x03) << 3) | (t1 >> 5)).ok_or(FrameError::BadTelId(*t0, *t1))?;
    let declared = t1 & 0x1F;
    if usize::from(declared) != data.len() || data.len() > MAX_DATA_LEN {
        return Err(FrameError::LengthMismatch {
            declared,
            actual: data.len(),
        });
    }
    let schunk = schunk_bcc([*t0, *t1], data);
    let player = player_bcc(module, data);
    let form = if *bcc == schunk {
        ChecksumForm::Schunk
    } else if *bcc == player {
        ChecksumForm::Player
    } else {
        return Err(FrameError::BadChecksum {
            received: *bcc,
            schunk,
            player,
        });
    };
    Ok((
        Frame {
            direction,
            module,
            data: Payload::new(data)?,
        },
        form,
    ))
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Discarding bytes until an STX.
    Hunting,
    /// Inside a telegram, collecting body bytes.
    Body,
    /// Inside a telegram, the previous byte was DLE.
    Escape,
}

/// Counters for diagnostics (e.g. to find out on real hardware which checksum form modules send).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    pub frames_schunk_bcc: u64,
    pub frames_player_bcc: u64,
    pub errors: u64,
    /// Bytes dropped while hunting for STX.
    pub skipped_bytes: u64,
}

/// Incremental telegram decoder for either direction: push bytes as they arrive, pop telegrams.
///
/// Resynchronisation: an unescaped STX can only start a telegram, so every STX restarts the
/// decoder (reporting [`FrameError::Interrupted`] if a telegram was in progress). Hence a complete,
/// valid telegram is always decoded, whatever bytes came before it; garbage can only add
/// items (errors, or telegrams that happen to be valid) *before* it.
#[derive(Debug)]
pub struct FrameDecoder {
    input: VecDeque<u8>,
    state: State,
    body: [u8; MAX_BODY_LEN],
    body_len: usize,
    stats: DecoderStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    pub fn new() -> Self {
        Self {
            input: VecDeque::new(),
            state: State::Hunting,
            body: [0; MAX_BODY_LEN],
            body_len: 0,
            stats: DecoderStats::default(),
        }
    }

    /// Queues received bytes; nothing is decoded until [`Self::next_frame`].
    pub fn push(&mut self, bytes: &[u8]) {
        self.input.extend(bytes);
    }

    /// Decodes queued bytes up to the next complete telegram or error; `None` when it needs more.
    pub fn next_frame(&mut self) -> Option<Result<Frame, FrameError>> {
        while let Some(b) = self.input.pop_front() {
            if let Some(item) = self.feed(b) {
                return Some(item);
            }
        }
        None
    }

    /// Runs one byte through the state machine, counting errors.
    fn feed(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        let item = self.step(byte);
        match &item {
            Some(Ok(_)) => {}
            Some(Err(_)) => self.stats.errors += 1,
            None => {}
        }
        item
    }

    /// Diagnostics counters.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Drops any partial telegram and queued bytes (e.g. after a reply timeout).
    pub fn reset(&mut self) {
        self.input.clear();
        self.state = State::Hunting;
        self.body_len = 0;
    }

    fn start_frame(&mut self) {
        self.state = State::Body;
        self.body_len = 0;
    }

    fn push_body(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        match self.body.get_mut(self.body_len) {
            Some(slot) => {
                *slot = byte;
                self.body_len += 1;
                self.state = State::Body;
                None
            }
            None => {
                self.state = State::Hunting;
                Some(Err(FrameError::BodyTooLong))
            }
        }
    }

    fn step(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        match (self.state, byte) {
            (State::Hunting, STX) => {
                self.start_frame();
                None
            }
            (State::Hunting, _) => {
                self.stats.skipped_bytes += 1;
                None
            }
            // An unescaped STX inside a telegram (or right after DLE, where it is not a valid
            // escape either) means the telegram was cut short: report and start over here.
            (State::Body, STX) => {
                let body_len = self.body_len;
                self.start_frame();
                Some(Err(FrameError::Interrupted { body_len }))
            }
            (State::Escape, STX) => {
                self.start_frame();
                Some(Err(FrameError::BadEscape(STX)))
            }
            (State::Body, ETX) => {
                self.state = State::Hunting;
                let body = self.body.get(..self.body_len).unwrap_or(&[]);
                let result = parse_body(body);
                Some(match result {
                    Ok((frame, form)) => {
                        match form {
                            ChecksumForm::Schunk => self.stats.frames_schunk_bcc += 1,
                            ChecksumForm::Player => self.stats.frames_player_bcc += 1,
                        }
                        Ok(frame)
                    }
                    Err(e) => Err(e),
                })
            }
            (State::Body, DLE) => {
                self.state = State::Escape;
                None
            }
            (State::Body, b) => self.push_body(b),
            (State::Escape, b) => {
                let unescaped = b.wrapping_sub(ESCAPE_OFFSET);
                if matches!(unescaped, STX | ETX | DLE) {
                    self.push_body(unescaped)
                } else {
                    self.state = State::Hunting;
                    Some(Err(FrameError::BadEscape(b)))
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(n: u8) -> ModuleId {
        ModuleId::new(n).expect("valid test module id")
    }

    fn decode_all(bytes: &[u8]) -> Vec<Result<Frame, FrameError>> {
        let mut d = FrameDecoder::new();
        d.push(bytes);
        std::iter::from_fn(|| d.next_frame()).collect()
    }

    #[test]
    fn get_ext_act_pos_to_module_12() {
        let bytes = encode_request(id(12), &[0x0A, 0x3C]).unwrap();
        assert_eq!(bytes, [0x02, 0x05, 0x82, 0x0A, 0x3C, 0xCD, 0x03]);
    }

    #[test]
    fn get_ext_act_pos_to_module_8_escapes_telid1() {
        let bytes = encode_request(id(8), &[0x0A, 0x3C]).unwrap();
        assert_eq!(bytes, [0x02, 0x05, 0x10, 0x82, 0x0A, 0x3C, 0x4D, 0x03]);
    }

    #[test]
    fn module_12_position_reply_decodes() {
        let wire = [0x02, 0x09, 0x86, 0x0A, 0x3C, 0x00, 0x00, 0x00, 0x3F, 0x15, 0x03];
        let frames = decode_all(&wire);
        assert_eq!(frames.len(), 1);
        let f = frames[0].unwrap();
        assert_eq!(f.direction, Direction::ToHost);
        assert_eq!(f.module, id(12));
        assert_eq!(f.data.as_slice(), [0x0A, 0x3C, 0x00, 0x00, 0x00, 0x3F]);
        let value = f32::from_le_bytes([0x00, 0x00, 0x00, 0x3F]);
        assert_eq!(value, 0.5);
        // And the mock-device side produces exactly these bytes.
        assert_eq!(encode_reply(id(12), f.data.as_slice()).unwrap(), wire);
    }

    #[test]
    fn requests_decode_too() {
        let frames = decode_all(&[0x02, 0x05, 0x10, 0x82, 0x0A, 0x3C, 0x4D, 0x03]);
        assert_eq!(
            frames,
            [Ok(Frame::request(id(8), Payload::new(&[0x0A, 0x3C]).unwrap()))]
        );
    }

    #[test]
    fn every_special_byte_is_escaped_in_telid_data_and_bcc() {
        // TelID1 is 0x02 / 0x03 for modules 8, 16, 24 with 2 / 3 data bytes. TelID1 can never be
        // 0x10 (that would need 16 data bytes) and TelID0 never is special (0x04..=0x0B).
        for (module, data) in [
            (8u8, &[0x01u8, 0x01][..]), // TelID1 0x02
            (8, &[0x01, 0x01, 0x01]),   // TelID1 0x03
            (16, &[0x02, 0x03, 0x10]),  // TelID1 0x03, every special in data
            (24, &[0x10, 0x10]),        // TelID1 0x02
        ] {
            let wire = encode_request(id(module), data).unwrap();
            let body = &wire[1..wire.len() - 1];
            assert!(!body.iter().any(|b| matches!(b, &STX | &ETX)), "{wire:02X?}");
            assert_eq!(
                decode_all(&wire),
                [Ok(Frame::request(id(module), Payload::new(data).unwrap()))]
            );
        }
    }

    #[test]
    fn escaped_telid_and_data_byte_literal() {
        // Module 16, data [02 03 10]: TelID 06 03, Schunk BCC 06+03+02+03+10 = 0x1E.
        let wire = encode_request(id(16), &[0x02, 0x03, 0x10]).unwrap();
        assert_eq!(
            wire,
            [0x02, 0x06, 0x10, 0x83, 0x10, 0x82, 0x10, 0x83, 0x10, 0x90, 0x1E, 0x03]
        );
        // The same from the module: TelID0 0x0A, BCC 0x0A+03+02+03+10 = 0x22.
        let wire = encode_reply(id(16), &[0x02, 0x03, 0x10]).unwrap();
        assert_eq!(
            wire,
            [0x02, 0x0A, 0x10, 0x83, 0x10, 0x82, 0x10, 0x83, 0x10, 0x90, 0x22, 0x03]
        );
    }

    #[test]
    fn bcc_of_each_special_value_is_escaped() {
        // Search the single-data-byte requests to module 1 for each special BCC, so the test does
        // not depend on hand arithmetic.
        for special in [STX, ETX, DLE] {
            let d = (0..=255u8)
                .find(|&d| schunk_bcc([0x04, 0x21], &[d]) == special)
                .expect("some data byte gives this BCC");
            let wire = encode_request(id(1), &[d]).unwrap();
            assert_eq!(wire[wire.len() - 3..], [DLE, special + 0x80, ETX], "{wire:02X?}");
            assert_eq!(
                decode_all(&wire),
                [Ok(Frame::request(id(1), Payload::new(&[d]).unwrap()))]
            );
        }
    }

    #[test]
    fn player_checksum_is_accepted() {
        // GET_EXT ACT_POS to module 12 with the Player BCC: (12 + 0x0A + 0x3C) = 0x52.
        assert_eq!(player_bcc(id(12), &[0x0A, 0x3C]), 0x52);
        let mut d = FrameDecoder::new();
        d.push(&[0x02, 0x05, 0x82, 0x0A, 0x3C, 0x52, 0x03]);
        assert_eq!(
            d.next_frame(),
            Some(Ok(Frame::request(id(12), Payload::new(&[0x0A, 0x3C]).unwrap())))
        );
        // The reply from module 12 with the Player BCC: 12 + 0x0A + 0x3C + 0x3F = 0x91.
        d.push(&[0x02, 0x09, 0x86, 0x0A, 0x3C, 0x00, 0x00, 0x00, 0x3F, 0x91, 0x03]);
        assert!(matches!(d.next_frame(), Some(Ok(f)) if f.module == id(12)));
        assert_eq!(d.stats().frames_player_bcc, 2);
        assert_eq!(d.stats().frames_schunk_bcc, 0);
    }

    #[test]
    fn bad_checksum_is_reported_and_next_frame_decodes() {
        let mut wire = vec![0x02, 0x05, 0x82, 0x0A, 0x3C, 0xCE, 0x03];
        wire.extend_from_slice(&[0x02, 0x05, 0x82, 0x0A, 0x3C, 0xCD, 0x03]);
        let items = decode_all(&wire);
        assert_eq!(
            items[0],
            Err(FrameError::BadChecksum {
                received: 0xCE,
                schunk: 0xCD,
                player: 0x52
            })
        );
        assert!(items[0].unwrap_err().is_checksum());
        assert!(items[1].is_ok());
        assert_eq!(items.len(), 2);
    }

    #[test]
    fn length_field_must_match() {
        // TelID1 says 3 data bytes, 2 present (BCC fixed up so only the length is wrong).
        let bcc = schunk_bcc([0x05, 0x83], &[0x0A, 0x3C]);
        assert_eq!(bcc, 0xCE);
        let items = decode_all(&[0x02, 0x05, 0x83, 0x0A, 0x3C, bcc, 0x03]);
        assert_eq!(items, [Err(FrameError::LengthMismatch { declared: 3, actual: 2 })]);
    }

    #[test]
    fn bad_escape_then_resync() {
        let mut wire = vec![0x02, 0x05, 0x10, 0x41, 0x0A];
        wire.extend_from_slice(&[0x02, 0x05, 0x82, 0x0A, 0x3C, 0xCD, 0x03]);
        let items = decode_all(&wire);
        assert_eq!(items[0], Err(FrameError::BadEscape(0x41)));
        assert!(items[1].is_ok());
    }

    #[test]
    fn interrupted_frame_and_garbage_before_stx() {
        let wire = [
            0xFF, 0x00, 0x41, 0x02, 0x05, 0x82, 0x02, 0x05, 0x82, 0x0A, 0x3C, 0xCD, 0x03,
        ];
        let mut d = FrameDecoder::new();
        d.push(&wire);
        assert_eq!(d.next_frame(), Some(Err(FrameError::Interrupted { body_len: 2 })));
        assert!(matches!(d.next_frame(), Some(Ok(_))));
        assert_eq!(d.next_frame(), None);
        assert_eq!(d.stats().skipped_bytes, 3);
    }

    #[test]
    fn too_long_and_too_short_bodies() {
        let mut long = vec![STX];
        long.extend_from_slice(&[0x41; 12]);
        long.push(ETX);
        assert_eq!(decode_all(&long), [Err(FrameError::BodyTooLong)]);
        assert_eq!(
            decode_all(&[STX, 0x05, 0x80, ETX]),
            [Err(FrameError::TooShort { len: 2 })]
        );
        assert_eq!(decode_all(&[STX, ETX]), [Err(FrameError::TooShort { len: 0 })]);
    }

    #[test]
    fn bad_telid_direction_and_module_zero() {
        assert!(matches!(
            decode_all(&[STX, 0x44, 0x80, 0xC4, ETX])[..],
            [Err(FrameError::BadTelId(0x44, 0x80))]
        ));
        // Module 0: TelID 04 00.
        assert!(matches!(
            decode_all(&[STX, 0x04, 0x00, 0x04, ETX])[..],
            [Err(FrameError::BadTelId(0x04, 0x00))]
        ));
    }

    #[test]
    fn byte_at_a_time_equals_all_at_once() {
        let wire = encode_request(id(8), &[0x08, 0x45, 0x02, 0x03, 0x10, 0x3F]).unwrap();
        let mut d = FrameDecoder::new();
        let mut got = Vec::new();
        for b in &wire {
            d.push(std::slice::from_ref(b));
            got.extend(std::iter::from_fn(|| d.next_frame()));
        }
        assert_eq!(got, decode_all(&wire));
        assert_eq!(got.len(), 1);
    }

    #[test]
    fn module_id_range_and_oversized_data() {
        assert!(ModuleId::new(0).is_none());
        assert!(ModuleId::new(32).is_none());
        assert_eq!(ModuleId::new(31).map(ModuleId::get), Some(31));
        assert_eq!(encode_request(id(1), &[0; 9]), Err(FrameError::DataTooLong { len: 9 }));
    }
}
