use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use flume::TrySendError;
use parking_lot::Mutex;
use tokio_tungstenite::tungstenite::Message;

use crate::throttler::Throttler;

static THROTTLER: Mutex<Throttler> = Mutex::new(Throttler::new(Duration::from_secs(30)));

#[derive(Debug, Clone, Copy)]
pub(crate) enum SendLossyResult {
    Sent,
    #[allow(dead_code)]
    SentLossy(usize),
    ExhaustedRetries,
}

/// Attempt to send a message on the channel.
///
/// If the channel is non-full, this function returns `SendLossyResult::Sent`.
///
/// If the channel is full, drop the oldest message and try again. If the send eventually succeeds
/// in this manner, this function returns `SendLossyResult::SentLossy(dropped)`. If the maximum
/// number of retries is reached, it returns `SendLossyResult::ExhaustedRetries`.
#[allow(dead_code)] // sqscan's patch sends through `send_lossy_bounded`.
pub(crate) fn send_lossy(
    client_addr: &SocketAddr,
    tx: &flume::Sender<Message>,
    rx: &flume::Receiver<Message>,
    mut message: Message,
    retries: usize,
) -> SendLossyResult {
    // If the queue is full, drop the oldest message(s). We do this because the WebSocket
    // client is falling behind, and we either start dropping messages, or we'll end up
    // buffering until we run out of memory. There's no point in that because the client is
    // unlikely to catch up and be able to consume the messages.
    let mut dropped = 0;
    loop {
        match (dropped, tx.try_send(message)) {
            (0, Ok(_)) => return SendLossyResult::Sent,
            (_, Ok(_)) => {
                if THROTTLER.lock().try_acquire() {
                    tracing::info!("outbox for client {client_addr} full");
                }
                return SendLossyResult::SentLossy(dropped);
            }
            (_, Err(TrySendError::Disconnected(_))) => unreachable!("we're holding rx"),
            (_, Err(TrySendError::Full(rejected))) => {
                if dropped >= retries {
                    if THROTTLER.lock().try_acquire() {
                        tracing::info!("outbox for client {client_addr} full");
                    }
                    return SendLossyResult::ExhaustedRetries;
                }
                message = rejected;
                let _ = rx.try_recv();
                dropped += 1
            }
        }
    }
}

/// [`send_lossy`] with the queue bounded by bytes as well (sqscan's patch): `bytes` counts the
/// bytes of the queued messages (the receiver subtracts what it takes); while the queue holds
/// more than `limit` with this message counted, the oldest messages are dropped. A message larger
/// than `limit` is still queued once the queue is empty, so that it can be delivered at all.
pub(crate) fn send_lossy_bounded(
    client_addr: &SocketAddr,
    tx: &flume::Sender<Message>,
    rx: &flume::Receiver<Message>,
    message: Message,
    retries: usize,
    bytes: &AtomicUsize,
    limit: usize,
) -> SendLossyResult {
    let len = message.len();
    // Counted before it is visible to the receiver, so the count never goes below zero.
    let mut total = bytes.fetch_add(len, Ordering::Relaxed).saturating_add(len);
    let mut dropped = 0;
    while total > limit {
        let Ok(old) = rx.try_recv() else { break };
        total = bytes.fetch_sub(old.len(), Ordering::Relaxed) - old.len();
        dropped += 1;
    }
    // Messages the count bound drops are taken off the byte count through `Counted`.
    let result = send_lossy_counted(client_addr, tx, rx, message, retries, bytes);
    match result {
        SendLossyResult::ExhaustedRetries => {
            bytes.fetch_sub(len, Ordering::Relaxed);
            result
        }
        SendLossyResult::Sent if dropped > 0 => {
            if THROTTLER.lock().try_acquire() {
                tracing::info!("outbox for client {client_addr} full");
            }
            SendLossyResult::SentLossy(dropped)
        }
        SendLossyResult::SentLossy(n) => SendLossyResult::SentLossy(n + dropped),
        SendLossyResult::Sent => result,
    }
}

/// [`send_lossy`], subtracting the bytes of every message it drops from `bytes`.
fn send_lossy_counted(
    client_addr: &SocketAddr,
    tx: &flume::Sender<Message>,
    rx: &flume::Receiver<Message>,
    mut message: Message,
    retries: usize,
    bytes: &AtomicUsize,
) -> SendLossyResult {
    let mut dropped = 0;
    loop {
        match (dropped, tx.try_send(message)) {
            (0, Ok(_)) => return SendLossyResult::Sent,
            (_, Ok(_)) => {
                if THROTTLER.lock().try_acquire() {
                    tracing::info!("outbox for client {client_addr} full");
                }
                return SendLossyResult::SentLossy(dropped);
            }
            (_, Err(TrySendError::Disconnected(_))) => unreachable!("we're holding rx"),
            (_, Err(TrySendError::Full(rejected))) => {
                if dropped >= retries {
                    if THROTTLER.lock().try_acquire() {
                        tracing::info!("outbox for client {client_addr} full");
                    }
                    return SendLossyResult::ExhaustedRetries;
                }
                message = rejected;
                if let Ok(old) = rx.try_recv() {
                    bytes.fetch_sub(old.len(), Ordering::Relaxed);
                }
                dropped += 1
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use assert_matches::assert_matches;
    use tracing_test::traced_test;

    use super::*;

    fn make_message(id: usize) -> Message {
        Message::Text(format!("{id}").into())
    }

    fn parse_message(msg: Message) -> usize {
        match msg {
            Message::Text(text) => text.parse().expect("id"),
            _ => unreachable!(),
        }
    }

    #[traced_test]
    #[test]
    fn test_send_lossy() {
        const BACKLOG: usize = 4;
        const TOTAL: usize = 10;

        let addr = SocketAddr::new("127.0.0.1".parse().unwrap(), 1234);

        let (tx, rx) = flume::bounded(BACKLOG);
        for i in 0..BACKLOG {
            assert_matches!(
                send_lossy(&addr, &tx, &rx, make_message(i), 0),
                SendLossyResult::Sent
            );
        }

        // The queue is full now. We'll only succeed with retries.
        for i in BACKLOG..TOTAL {
            assert_matches!(
                send_lossy(&addr, &tx, &rx, make_message(TOTAL + i), 0),
                SendLossyResult::ExhaustedRetries
            );
            assert_matches!(
                send_lossy(&addr, &tx, &rx, make_message(i), 1),
                SendLossyResult::SentLossy(1)
            );
        }

        // Receive everything, expect that the first (TOTAL - BACKLOG) messages were dropped.
        let mut received: Vec<usize> = vec![];
        while let Ok(msg) = rx.try_recv() {
            received.push(parse_message(msg));
        }
        assert_eq!(received, ((TOTAL - BACKLOG)..TOTAL).collect::<Vec<_>>());
    }

    /// sqscan's patch: a backlog of 1,000 messages that a client never reads holds at most the
    /// byte bound (plus one message larger than it), dropping the oldest.
    #[test]
    fn test_send_lossy_bounded_by_bytes() {
        let addr = SocketAddr::new("127.0.0.1".parse().unwrap(), 1234);
        let (tx, rx) = flume::bounded(1000);
        let bytes = AtomicUsize::new(0);
        let big = |i: usize| Message::Binary(vec![i as u8; 1000].into());
        for i in 0..100 {
            send_lossy_bounded(&addr, &tx, &rx, big(i), 10, &bytes, 3500);
            assert!(bytes.load(Ordering::Relaxed) <= 3500);
        }
        assert_eq!(rx.len(), 3);
        assert_eq!(bytes.load(Ordering::Relaxed), 3000);
        // A message over the bound goes out alone.
        let huge = Message::Binary(vec![0; 10_000].into());
        send_lossy_bounded(&addr, &tx, &rx, huge, 10, &bytes, 3500);
        assert_eq!((rx.len(), bytes.load(Ordering::Relaxed)), (1, 10_000));
        // The receiver's share: what it takes is taken off the count (as the poller does).
        let m = rx.try_recv().unwrap();
        bytes.fetch_sub(m.len(), Ordering::Relaxed);
        assert_eq!(bytes.load(Ordering::Relaxed), 0);
        // The count bound still holds, and keeps the byte count true.
        let (tx, rx) = flume::bounded(2);
        let bytes = AtomicUsize::new(0);
        for i in 0..5 {
            send_lossy_bounded(&addr, &tx, &rx, big(i), 10, &bytes, usize::MAX);
        }
        assert_eq!((rx.len(), bytes.load(Ordering::Relaxed)), (2, 2000));
    }
}
