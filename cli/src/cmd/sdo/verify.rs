//! `sdo write --verify`: the value read back, compared byte by byte with what was written as it
//! arrives, so a verified 100 MiB image costs no more memory than a buffer.

use std::io::Read;
use std::pin::Pin;
use std::task::{Context, Poll};
use tokio::io::AsyncWrite;

/// A writer that compares what it is given with `src`.
pub struct Compare {
    src: Box<dyn Read + Send>,
    buf: Vec<u8>,
    /// Bytes compared so far.
    pos: u64,
    /// The offset of the first byte that differs, or where `src` ended early.
    first_diff: Option<u64>,
}

impl Compare {
    /// Compares with `src`.
    pub fn new(src: Box<dyn Read + Send>) -> Compare {
        Compare {
            src,
            buf: Vec::new(),
            pos: 0,
            first_diff: None,
        }
    }

    /// The verdict once `read` bytes came back of the `written`.
    pub fn check(mut self, read: u64, written: u64) -> Result<(), String> {
        if let Some(at) = self.first_diff {
            return Err(format!("byte {at} differs"));
        }
        if read != written {
            return Err(format!("{read} bytes read back, {written} written"));
        }
        // Anything left in the source means the node returned less than the source holds.
        let mut one = [0u8; 1];
        match self.src.read(&mut one) {
            Ok(0) => Ok(()),
            Ok(_) => Err(format!("the value read back ends at byte {read}")),
            Err(e) => Err(e.to_string()),
        }
    }
}

impl AsyncWrite for Compare {
    fn poll_write(
        mut self: Pin<&mut Self>,
        _: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let me = &mut *self;
        if me.first_diff.is_none() {
            me.buf.resize(data.len(), 0);
            // A local file (or memory): a short blocking read is fine here.
            let mut got = 0;
            while got < data.len() {
                match me.src.read(&mut me.buf[got..]) {
                    Ok(0) => break,
                    Ok(n) => got += n,
                    Err(e) => return Poll::Ready(Err(e)),
                }
            }
            let same = data[..got]
                .iter()
                .zip(&me.buf[..got])
                .position(|(a, b)| a != b);
            match same {
                Some(i) => me.first_diff = Some(me.pos + i as u64),
                None if got < data.len() => me.first_diff = Some(me.pos + got as u64),
                None => {}
            }
        }
        me.pos += data.len() as u64;
        Poll::Ready(Ok(data.len()))
    }
    fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Poll::Ready(Ok(()))
    }
    fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;

    async fn verdict(src: &[u8], back: &[&[u8]]) -> Result<(), String> {
        let mut c = Compare::new(Box::new(std::io::Cursor::new(src.to_vec())));
        let mut n = 0;
        for chunk in back {
            c.write_all(chunk).await.unwrap();
            n += chunk.len() as u64;
        }
        c.check(n, src.len() as u64)
    }

    #[tokio::test]
    async fn equal_differing_short_and_long() {
        assert_eq!(verdict(b"abcdef", &[b"abc", b"def"]).await, Ok(()));
        assert_eq!(
            verdict(b"abcdef", &[b"abc", b"dXf"]).await,
            Err("byte 4 differs".into())
        );
        assert_eq!(
            verdict(b"abcdef", &[b"abc"]).await,
            Err("3 bytes read back, 6 written".into())
        );
        assert_eq!(
            verdict(b"abc", &[b"abcd"]).await,
            Err("byte 3 differs".into())
        );
    }
}
