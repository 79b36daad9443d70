//! Request lines from a client, bounded in length and safe to cancel.

use tokio::io::{AsyncBufRead, AsyncBufReadExt};

use super::config::MAX_REQUEST_BYTES;

/// Request lines of at most [`MAX_REQUEST_BYTES`], read so that a read cancelled at its await
/// (the client loop also waits on its timers and tasks) loses nothing: what was taken from the
/// reader is kept here until its line is complete.
#[derive(Default)]
pub(super) struct LineReader {
    /// The line read so far; a whole line once `next` says so.
    pub(super) buf: Vec<u8>,
    /// Bytes of an over-long line skipped so far.
    too_long: usize,
}

impl LineReader {
    /// The next line: `Ok(Some(Ok(())))` with the line in `self.buf` (without its newline),
    /// `Ok(None)` at end of input, or `Ok(Some(Err(len)))` for an over-long line, whose rest has
    /// been skipped up to its newline.
    pub(super) async fn next<R: AsyncBufRead + Unpin>(
        &mut self,
        r: &mut R,
    ) -> std::io::Result<Option<Result<(), usize>>> {
        loop {
            let chunk = r.fill_buf().await?;
            if chunk.is_empty() {
                // End of input; a last line without its newline still counts.
                let too_long = std::mem::take(&mut self.too_long);
                return Ok(if self.buf.is_empty() && too_long == 0 {
                    None
                } else if too_long > 0 {
                    Some(Err(too_long))
                } else {
                    Some(Ok(()))
                });
            }
            let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (chunk.len(), false),
            };
            if self.too_long == 0 && self.buf.len() + take <= MAX_REQUEST_BYTES + 1 {
                self.buf.extend_from_slice(&chunk[..take]);
            } else {
                self.too_long += self.buf.len() + take;
                self.buf.clear();
            }
            r.consume(take);
            if done {
                let too_long = std::mem::take(&mut self.too_long);
                if too_long > 0 {
                    return Ok(Some(Err(too_long)));
                }
                while self.buf.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
                    self.buf.pop();
                }
                return Ok(Some(Ok(())));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use tokio::io::{AsyncWriteExt, BufReader};

    async fn lines(input: &[u8]) -> Vec<Result<String, usize>> {
        let mut r = BufReader::with_capacity(7, input);
        let mut reader = LineReader::default();
        let mut out = Vec::new();
        while let Some(x) = reader.next(&mut r).await.unwrap() {
            out.push(x.map(|()| String::from_utf8(std::mem::take(&mut reader.buf)).unwrap()));
        }
        out
    }

    #[tokio::test]
    async fn request_lines_are_bounded() {
        let mut input = b"{\"cmd\":\"status\"}\r\n".to_vec();
        input.extend(vec![b'x'; MAX_REQUEST_BYTES + 10]);
        input.extend(b"\n{\"cmd\":\"models\"}");
        let got = lines(&input).await;
        assert_eq!(got.len(), 3, "{got:?}");
        assert_eq!(got[0], Ok("{\"cmd\":\"status\"}".to_string()));
        assert_eq!(got[1], Err(MAX_REQUEST_BYTES + 11));
        assert_eq!(got[2], Ok("{\"cmd\":\"models\"}".to_string()));
        // Exactly at the limit is fine.
        let mut at = vec![b' '; MAX_REQUEST_BYTES];
        at.push(b'\n');
        assert!(matches!(lines(&at).await[..], [Ok(_)]));
    }

    /// A read cancelled in the middle of a line (the client loop also waits on timers and
    /// tasks) loses none of it.
    #[tokio::test]
    async fn a_line_read_in_parts_survives_cancelled_reads() {
        let (mut w, r) = tokio::io::duplex(64);
        let mut r = BufReader::new(r);
        let mut reader = LineReader::default();
        w.write_all(b"{\"cmd\":").await.unwrap();
        let cut = tokio::time::timeout(Duration::from_millis(50), reader.next(&mut r)).await;
        assert!(cut.is_err(), "no line yet");
        w.write_all(b"\"status\"}\n").await.unwrap();
        assert!(matches!(reader.next(&mut r).await.unwrap(), Some(Ok(()))));
        assert_eq!(reader.buf, b"{\"cmd\":\"status\"}");
    }
}
