//! An `.mcap` file's records read where they lie: the file is mapped into memory and walked
//! record by record (the framing: an opcode byte and a little-endian u64 length before each
//! record's content), each record parsed by the MCAP library. A message of an uncompressed chunk
//! (rosbag2's default) is handed out without being copied; a compressed chunk is decompressed
//! whole by the library (CRC checked). The pages passed are given back to the system as the
//! reading moves on, so the memory a bag holds stays flat however large it is.

use std::ops::Range;
use std::path::{Path, PathBuf};

use mcap::records::{op, Record};

use crate::error::{Error, Result};

/// Bytes read before the pages behind the reading are given back (a multiple of any page size).
const RELEASE: usize = 4 << 20;

/// A mapped `.mcap` file, read from its start.
pub(super) struct Records {
    map: memmap2::Mmap,
    path: PathBuf,
    /// Where the next record of the file (outside any chunk) starts.
    at: usize,
    chunk: Chunk,
    /// The pages before this offset have been given back.
    released: usize,
}

/// The chunk being read.
enum Chunk {
    None,
    /// An uncompressed chunk's records still to read: their span of the map.
    Plain(Range<usize>),
    /// A compressed chunk's records still to read, decompressed.
    Unpacked(std::vec::IntoIter<Record<'static>>),
}

/// A record as framed in the file: its opcode, its content, and where the next record starts.
type Framed<'a> = (u8, &'a [u8], usize);

/// The record at `at` of `buf`: `None` at the end of `buf`, an error when it breaks off.
fn frame(buf: &[u8], at: usize) -> std::result::Result<Option<Framed<'_>>, String> {
    const HEAD: usize = 1 + 8;
    if at >= buf.len() {
        return Ok(None);
    }
    let broken = || format!("the file breaks off in the record at byte {at}");
    let head = buf.get(at..at + HEAD).ok_or_else(broken)?;
    let len = u64::from_le_bytes(head[1..].try_into().expect("eight bytes"));
    let end = usize::try_from(len)
        .ok()
        .and_then(|l| (at + HEAD).checked_add(l))
        .filter(|&e| e <= buf.len())
        .ok_or_else(broken)?;
    Ok(Some((head[0], &buf[at + HEAD..end], end)))
}

impl Records {
    /// Maps the file at `path` (which must start with MCAP's magic).
    pub fn open(path: &Path) -> Result<Records> {
        let (file, _) = crate::fs::open(path)?;
        // SAFETY: the file is only read. A bag is not modified in place once written (a
        // recording in progress only grows, beyond the length mapped here).
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        if !map.starts_with(mcap::MAGIC) {
            return Err(Error::format(
                path,
                "not an MCAP file (no MCAP magic at its start)",
            ));
        }
        Ok(Records {
            at: mcap::MAGIC.len(),
            map,
            path: path.into(),
            chunk: Chunk::None,
            released: 0,
        })
    }

    /// The next record of the data section, chunks opened: `None` at its end (or at the end of
    /// a file that breaks off between records, an unfinished recording). An error names the
    /// file and `context`.
    pub fn next(&mut self, context: &dyn Fn() -> String) -> Result<Option<Record<'_>>> {
        let fail = |e: String| Error::format(&self.path, format!("{}: {e}", context()));
        let parse = |op: u8, body| {
            mcap::parse_record(op, body).map_err(|e| Error::mcap(&self.path, context(), e))
        };
        loop {
            match &mut self.chunk {
                Chunk::Plain(span) if span.start < span.end => {
                    let (op, body, next) = frame(&self.map[..span.end], span.start)
                        .map_err(fail)?
                        .expect("a record in the span");
                    span.start = next;
                    return parse(op, body).map(Some);
                }
                Chunk::Unpacked(records) => {
                    if let Some(r) = records.next() {
                        return Ok(Some(r));
                    }
                }
                _ => {}
            }
            self.chunk = Chunk::None;
            release(&self.map, &mut self.released, self.at);
            let Some((op, body, next)) = frame(&self.map, self.at).map_err(fail)? else {
                return Ok(None);
            };
            self.at = next;
            match op {
                op::DATA_END | op::FOOTER => {
                    self.at = self.map.len();
                    return Ok(None);
                }
                op::CHUNK => self.chunk = self.chunk(parse(op, body)?, context)?,
                _ => return parse(op, body).map(Some),
            }
        }
    }

    /// The records of a chunk record: where they lie when it is uncompressed, else decompressed.
    fn chunk(&self, record: Record<'_>, context: &dyn Fn() -> String) -> Result<Chunk> {
        let Record::Chunk { header, data } = record else {
            unreachable!("a chunk record parses as a chunk");
        };
        let mcap_err = |e| Error::mcap(&self.path, context(), e);
        if header.compression.is_empty() {
            if let std::borrow::Cow::Borrowed(d) = data {
                let start = d.as_ptr() as usize - self.map.as_ptr() as usize;
                return Ok(Chunk::Plain(start..start + d.len()));
            }
        }
        let records = mcap::read::ChunkReader::new(header, &data)
            .map_err(mcap_err)?
            .map(|r| r.map(Record::into_owned))
            .collect::<mcap::McapResult<Vec<_>>>()
            .map_err(mcap_err)?;
        Ok(Chunk::Unpacked(records.into_iter()))
    }
}

/// Gives back the pages of `map` before `at` not given back yet (those before `released`), every
/// [`RELEASE`] bytes.
fn release(map: &memmap2::Mmap, released: &mut usize, at: usize) {
    let upto = at / RELEASE * RELEASE;
    if upto > *released {
        // SAFETY (Unix; elsewhere the pages stay mapped): nothing borrowed from the map before
        // `at` is alive (a record read from it borrows the reader); the mapping is read-only
        // and backed by the file, so a later access (there is none) would read the file again.
        #[cfg(unix)]
        let _ = unsafe {
            map.unchecked_advise_range(
                memmap2::UncheckedAdvice::DontNeed,
                *released,
                upto - *released,
            )
        };
        *released = upto;
    }
}
