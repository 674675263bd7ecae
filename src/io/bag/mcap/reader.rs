//! Reading a storage file: a buffered reader that knows its position, and the decompression
//! of a chunk's records.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A buffered reader that knows its position, so that forward skips keep the buffer.
pub(super) struct Reader {
    inner: BufReader<File>,
    pos: u64,
    path: PathBuf,
}

impl Reader {
    pub(super) fn open(path: &Path) -> Result<Reader> {
        let f = File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(Reader {
            inner: BufReader::with_capacity(1 << 16, f),
            pos: 0,
            path: path.to_path_buf(),
        })
    }
    pub(super) fn err(&self, e: std::io::Error) -> Error {
        Error::io(&self.path, e)
    }
    pub(super) fn goto(&mut self, to: u64) -> Result<()> {
        if to == self.pos {
            return Ok(());
        }
        let r = match i64::try_from(to.wrapping_sub(self.pos)) {
            Ok(d) if to > self.pos => self.inner.seek_relative(d),
            _ => self.inner.seek(SeekFrom::Start(to)).map(|_| ()),
        };
        r.map_err(|e| self.err(e))?;
        self.pos = to;
        Ok(())
    }
    /// Reads exactly `n` bytes at `at` into `buf` (replacing its content). The caller has
    /// checked that they lie inside the file.
    pub(super) fn read_into(&mut self, at: u64, n: u64, buf: &mut Vec<u8>) -> Result<()> {
        self.goto(at)?;
        buf.clear();
        let got = (&mut self.inner)
            .take(n)
            .read_to_end(buf)
            .map_err(|e| Error::io(&self.path, e))?;
        self.pos += got as u64;
        if (got as u64) < n {
            return Err(Error::Input(format!(
                "{}: the file ended at byte {} while {} bytes were expected there (it was \
                 shortened while being read?)",
                self.path.display(),
                self.pos,
                n
            )));
        }
        Ok(())
    }
    pub(super) fn read_array<const N: usize>(&mut self, at: u64) -> Result<[u8; N]> {
        self.goto(at)?;
        let mut b = [0u8; N];
        self.inner.read_exact(&mut b).map_err(|e| self.err(e))?;
        self.pos += N as u64;
        Ok(b)
    }
    /// A record's opcode and length at `at` (the caller has checked 9 bytes are there).
    pub(super) fn record_head(&mut self, at: u64) -> Result<(u8, u64)> {
        let h: [u8; 9] = self.read_array(at)?;
        let mut len = [0u8; 8];
        len.copy_from_slice(&h[1..]);
        Ok((h[0], u64::from_le_bytes(len)))
    }
}

/// Decompresses (`zstd`, otherwise lz4) the `stored` bytes of a chunk's records at the
/// reader's position into `out`,
/// at most `size + 1` bytes; a panic of the third-party decompressor is an error.
pub(super) fn decompress(
    r: &mut Reader,
    compression: &str,
    stored: u64,
    size: u64,
    out: &mut Vec<u8>,
) -> std::result::Result<(), String> {
    out.clear();
    out.reserve(
        usize::try_from(size.min(stored.saturating_mul(8).saturating_add(1 << 16))).unwrap_or(0),
    );
    let src = (&mut r.inner).take(stored);
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match compression {
        "zstd" => {
            zstd::stream::read::Decoder::new(src).and_then(|d| d.take(size + 1).read_to_end(out))
        }
        _ => lz4::Decoder::new(src).and_then(|d| d.take(size + 1).read_to_end(out)),
    }));
    // The reader's position is unknown after the decoder; the caller moves it.
    r.pos = u64::MAX;
    match res {
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => Err(format!("{compression} decompression failed: {e}")),
        Err(_) => Err(format!("the {compression} decompressor failed")),
    }
}
