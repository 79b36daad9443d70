//! Property tests for every incremental decoder: no input makes them panic, and a valid item
//! that follows arbitrary garbage is still decoded (what each decoder's resynchronisation
//! guarantees, exactly as its docs state it).

use proptest::prelude::*;
use sqscan_drivers::flir::{Axis, Number, PtuReply, ReplyParser};
use sqscan_drivers::powercube::{
    Command, Direction, Frame, FrameDecoder, FrameError, ModuleId, Payload, Reply, player_bcc,
};
use sqscan_drivers::profile::{Profile, ProfileDecoder, ProfileError, SeqEvent, SequenceTracker};
use sqscan_drivers::profile::{encode_profile, frame::MAX_FRAME_LEN};

/// Splits `bytes` at the given (wrapped) chunk sizes and feeds them one chunk at a time.
fn chunks<'a>(bytes: &'a [u8], sizes: &'a [usize]) -> Vec<&'a [u8]> {
    let mut out = Vec::new();
    let mut rest = bytes;
    let mut i = 0;
    while !rest.is_empty() {
        let n = sizes
            .get(i % sizes.len().max(1))
            .copied()
            .unwrap_or(rest.len())
            .clamp(1, rest.len());
        let (a, b) = rest.split_at(n);
        out.push(a);
        rest = b;
        i += 1;
    }
    out
}

fn pc_decode(bytes: &[u8], sizes: &[usize]) -> Vec<Result<Frame, FrameError>> {
    let mut d = FrameDecoder::new();
    let mut items = Vec::new();
    for c in chunks(bytes, sizes) {
        d.push(c);
        while let Some(item) = d.next_frame() {
            items.push(item);
        }
    }
    items
}

fn arb_frame() -> impl Strategy<Value = Frame> {
    (1u8..=31, any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=8)).prop_map(|(id, to_host, data)| {
        let module = ModuleId::new(id).expect("1..=31");
        let data = Payload::new(&data).expect("<= 8 bytes");
        if to_host {
            Frame::reply(module, data)
        } else {
            Frame::request(module, data)
        }
    })
}

/// Bytes biased towards the PowerCube control characters, so the decoder's states get visited.
fn pc_noise() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(
        prop_oneof![any::<u8>(), Just(0x02u8), Just(0x03u8), Just(0x10u8), Just(0x82u8)],
        0..200,
    )
}

/// A telegram with the CARMEN/Player checksum, escaped by hand.
fn encode_with_player_bcc(f: &Frame) -> Vec<u8> {
    let telid = f.telid();
    let bcc = player_bcc(f.module, f.data.as_slice());
    let mut out = vec![0x02];
    for &b in telid.iter().chain(f.data.as_slice()).chain([bcc].iter()) {
        if matches!(b, 0x02 | 0x03 | 0x10) {
            out.extend([0x10, b + 0x80]);
        } else {
            out.push(b);
        }
    }
    out.push(0x03);
    out
}

proptest! {
    #[test]
    fn powercube_decoder_never_panics(bytes in pc_noise(), sizes in proptest::collection::vec(1usize..16, 1..8)) {
        let items = pc_decode(&bytes, &sizes);
        // Each item consumes at least one byte.
        prop_assert!(items.len() <= bytes.len());
    }

    #[test]
    fn powercube_data_parsers_never_panic(data in proptest::collection::vec(any::<u8>(), 0..=8)) {
        // The mock module parses requests, the driver parses replies: neither may panic.
        let _ = Command::parse(&data);
        let _ = Reply::parse(&data);
        // Whatever parses as a command re-encodes to the same bytes.
        if let Ok(cmd) = Command::parse(&data) {
            let payload = cmd.payload();
            prop_assert_eq!(payload.as_slice(), &data[..]);
        }
    }

    #[test]
    fn powercube_round_trip(frame in arb_frame(), sizes in proptest::collection::vec(1usize..16, 1..8)) {
        prop_assert_eq!(pc_decode(&frame.encode(), &sizes), vec![Ok(frame)]);
        prop_assert_eq!(pc_decode(&encode_with_player_bcc(&frame), &sizes), vec![Ok(frame)]);
    }

    /// Every unescaped STX restarts the decoder, so a complete valid telegram is decoded
    /// whatever precedes it (even garbage holding STX, DLE or a half telegram), and it is the
    /// last item: garbage can only add items before it.
    #[test]
    fn powercube_resyncs_after_any_garbage(
        garbage in pc_noise(),
        frame in arb_frame(),
        sizes in proptest::collection::vec(1usize..16, 1..8),
    ) {
        let mut bytes = garbage;
        bytes.extend(frame.encode());
        let items = pc_decode(&bytes, &sizes);
        prop_assert_eq!(items.last(), Some(&Ok(frame)));
    }

    #[test]
    fn flir_parser_never_panics(bytes in proptest::collection::vec(
        prop_oneof![any::<u8>(), Just(b'*'), Just(b'!'), Just(b'\r'), Just(b'\n'), Just(b'P'), Just(b' ')],
        0..600,
    )) {
        let mut p = ReplyParser::new();
        p.push(&bytes);
        p.flush_line();
        while p.next_reply().is_some() {}
    }

    /// Resynchronisation is per line: after a line end, a valid reply line parses exactly.
    #[test]
    fn flir_resyncs_at_line_end(
        garbage in proptest::collection::vec(any::<u8>(), 0..300),
        value in any::<i32>(),
        crlf in any::<bool>(),
    ) {
        let mut p = ReplyParser::new();
        p.push(&garbage);
        p.push(if crlf { b"\r\n" } else { b"\r" });
        p.push(format!("* {value}\r\n").as_bytes());
        let items: Vec<_> = std::iter::from_fn(|| p.next_reply()).collect();
        prop_assert_eq!(items.last(), Some(&PtuReply::Value(Number::Int(i64::from(value)))));
    }

    /// Without a line end, garbage free of markers and line ends is taken for echo.
    #[test]
    fn flir_echo_like_prefix_is_skipped(prefix in "[a-zA-Z0-9 .,-]{0,60}", value in any::<i32>()) {
        let mut p = ReplyParser::new();
        p.push(format!("{prefix}* {value}\r\n!P\r\n").as_bytes());
        let items: Vec<_> = std::iter::from_fn(|| p.next_reply()).collect();
        prop_assert_eq!(items, vec![PtuReply::Value(Number::Int(i64::from(value))), PtuReply::LimitHit(Axis::Pan)]);
    }
}

fn arb_profile() -> impl Strategy<Value = Profile> {
    (1usize..64, any::<u32>(), any::<u64>(), 0u8..=15, any::<bool>()).prop_flat_map(
        |(n, seq, timestamp_ns, fraction_bits, with_intensity)| {
            (
                proptest::collection::vec(any::<u16>(), n),
                proptest::collection::vec(any::<u8>(), n),
            )
                .prop_map(move |(rows, intensity)| Profile {
                    seq,
                    timestamp_ns,
                    fraction_bits,
                    rows,
                    intensity: with_intensity.then_some(intensity),
                })
        },
    )
}

fn profile_decode(bytes: &[u8], sizes: &[usize]) -> Vec<Result<Profile, ProfileError>> {
    let mut d = ProfileDecoder::new();
    let mut items = Vec::new();
    for c in chunks(bytes, sizes) {
        d.push(c);
        while let Some(item) = d.next_profile() {
            items.push(item);
        }
    }
    items
}

fn contains_magic(b: &[u8]) -> bool {
    b.windows(4).any(|w| w == b"SQPF")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn profile_decoder_never_panics(
        bytes in proptest::collection::vec(any::<u8>(), 0..400),
        magic_at in proptest::collection::vec(any::<prop::sample::Index>(), 0..4),
        sizes in proptest::collection::vec(1usize..64, 1..8),
    ) {
        // Plant magics so the header checks run on arbitrary headers, not just the scan.
        let mut bytes = bytes;
        for at in magic_at {
            if !bytes.is_empty() {
                let i = at.index(bytes.len());
                let end = (i + 4).min(bytes.len());
                bytes.splice(i..end, *b"SQPF");
            }
        }
        let _ = profile_decode(&bytes, &sizes);
    }

    #[test]
    fn profile_round_trip(p in arb_profile(), sizes in proptest::collection::vec(1usize..64, 1..8)) {
        let bytes = encode_profile(&p).expect("valid profile");
        prop_assert_eq!(profile_decode(&bytes, &sizes), vec![Ok(p)]);
    }

    /// Garbage without the magic: the frame is decoded as soon as it is complete.
    #[test]
    fn profile_resyncs_after_garbage(
        garbage in proptest::collection::vec(any::<u8>(), 0..500),
        p in arb_profile(),
        sizes in proptest::collection::vec(1usize..64, 1..8),
    ) {
        prop_assume!(!contains_magic(&garbage));
        let mut bytes = garbage;
        bytes.extend(encode_profile(&p).expect("valid profile"));
        let items = profile_decode(&bytes, &sizes);
        prop_assert_eq!(items.last(), Some(&Ok(p)));
    }

    /// Garbage holding a magic and a plausible header claims up to MAX_FRAME_LEN bytes; the
    /// valid frame inside that span is decoded once the candidate's CRC fails, i.e. after at
    /// most MAX_FRAME_LEN more bytes.
    #[test]
    fn profile_resyncs_after_a_fake_header(
        fake_header in proptest::collection::vec(any::<u8>(), 20),
        columns in 1u16..=8192,
        p in arb_profile(),
    ) {
        let mut bytes = b"SQPF".to_vec();
        bytes.extend(&fake_header);
        // Make the fake header plausible most of the time, so the long wait is exercised.
        bytes[4] = 1;
        bytes[5] &= 1;
        bytes[6..8].copy_from_slice(&24u16.to_le_bytes());
        bytes[20..22].copy_from_slice(&columns.to_le_bytes());
        bytes[22] %= 16;
        bytes[23] = 16;
        bytes.extend(encode_profile(&p).expect("valid profile"));
        bytes.extend(std::iter::repeat_n(0u8, MAX_FRAME_LEN));
        let items = profile_decode(&bytes, &[4096]);
        prop_assert_eq!(items.iter().rfind(|i| i.is_ok()), Some(&Ok(p)));
    }

    /// Strictly increasing (wrapping) sequence numbers: drops are exactly the skipped numbers.
    #[test]
    fn sequence_tracker_counts_drops(start in any::<u32>(), steps in proptest::collection::vec(1u32..50, 1..100)) {
        let mut t = SequenceTracker::default();
        prop_assert_eq!(t.observe(start), SeqEvent::First);
        let mut seq = start;
        for s in &steps {
            seq = seq.wrapping_add(*s);
            let ev = t.observe(seq);
            if *s == 1 {
                prop_assert_eq!(ev, SeqEvent::InOrder);
            } else {
                let is_gap = matches!(ev, SeqEvent::Gap { missing, .. } if missing == s - 1);
                prop_assert!(is_gap);
            }
        }
        let dropped: u64 = steps.iter().map(|s| u64::from(s - 1)).sum();
        prop_assert_eq!(t.counts().dropped, dropped);
        prop_assert_eq!(t.counts().late + t.counts().duplicates + t.counts().restarts, 0);
    }
}

#[test]
fn decoded_frames_keep_their_direction() {
    // Requests and replies carry their direction through the round trip.
    let m = ModuleId::new(3).expect("valid");
    let f = Frame::request(m, Payload::default());
    assert_eq!(
        pc_decode(&f.encode(), &[1])[0].map(|f| f.direction),
        Ok(Direction::ToModule)
    );
}
