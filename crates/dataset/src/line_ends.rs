//! Line ends as the csv reader needs them to place records.

use std::io::{self, Read};

/// A reader that turns each `\r\n` into `\n` (a lone `\r` passes). With `\r\n` line ends
/// the csv crate's record positions come out one line early (a bad cell on line 300 was
/// placed on line 299), and it has no option to change that; read through this, every
/// record is placed on the line an editor shows.
pub struct CrlfToLf<R> {
    inner: R,
    /// A `\r` ending the previous read, held until the next byte shows what it ends.
    pending_cr: bool,
    buf: Vec<u8>,
}

impl<R: Read> CrlfToLf<R> {
    /// Reads `inner` with its `\r\n` line ends as `\n`.
    pub fn new(inner: R) -> Self {
        CrlfToLf {
            inner,
            pending_cr: false,
            buf: Vec::new(),
        }
    }
}

impl<R: Read> Read for CrlfToLf<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        // Room for a held `\r` besides what is read.
        if out.len() < 2 {
            return Err(io::Error::other("read buffer too small"));
        }
        loop {
            self.buf.resize(out.len() - 1, 0);
            let n = match self.inner.read(&mut self.buf) {
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if n == 0 {
                let held = std::mem::take(&mut self.pending_cr);
                out[0] = b'\r';
                return Ok(usize::from(held));
            }
            let mut w = 0;
            if std::mem::take(&mut self.pending_cr) && self.buf[0] != b'\n' {
                out[w] = b'\r';
                w += 1;
            }
            for i in 0..n {
                let b = self.buf[i];
                if b == b'\r' {
                    match self.buf[..n].get(i + 1) {
                        Some(b'\n') => continue,
                        None => {
                            self.pending_cr = true;
                            continue;
                        }
                        Some(_) => {}
                    }
                }
                out[w] = b;
                w += 1;
            }
            if w > 0 {
                return Ok(w);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hands out its text a few bytes at a time, so that `\r\n` falls across reads.
    struct Trickle<'a> {
        text: &'a [u8],
        step: usize,
    }

    impl Read for Trickle<'_> {
        fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
            let n = self.step.min(out.len()).min(self.text.len());
            out[..n].copy_from_slice(&self.text[..n]);
            self.text = &self.text[n..];
            Ok(n)
        }
    }

    #[test]
    fn every_crlf_becomes_lf_and_nothing_else_changes() {
        let text = "a,b\r\n1,2\r\n\r\nx\ry\r\n3,4\r";
        let want = "a,b\n1,2\n\nx\ry\n3,4\r";
        for step in 1..=7 {
            for capacity in [2, 3, 5, 64] {
                let mut reader = CrlfToLf::new(Trickle {
                    text: text.as_bytes(),
                    step,
                });
                let mut got = Vec::new();
                let mut chunk = vec![0; capacity];
                loop {
                    let n = reader.read(&mut chunk).unwrap();
                    if n == 0 {
                        break;
                    }
                    got.extend_from_slice(&chunk[..n]);
                }
                assert_eq!(
                    String::from_utf8(got).unwrap(),
                    want,
                    "step {step}, buffer {capacity}"
                );
            }
        }
    }
}
