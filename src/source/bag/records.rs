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
    /// Where the chunk being read starts.
    chunk_at: usize,
}

/// The chunk being read.
enum Chunk {
    None,
    /// An uncompressed chunk's records still to read: their span of the map.
    Plain(Range<usize>),
    /// A compressed chunk's records still to read, decompressed.
    Unpacked(std::vec::IntoIter<Record<'static>>),
}

/// What the walk gives: a record, or the place of one whose framing is whole but whose content
/// is not (a chunk failing its CRC or its decompression, a record that does not parse). The walk
/// goes on after it; only a broken framing ends the file.
pub(super) enum Item<'a> {
    /// A record.
    Record(Record<'a>),
    /// A damaged record.
    Damaged(Damage),
}

/// A record of the file that could not be read (see [`Item::Damaged`]).
#[derive(Debug)]
pub struct Damage {
    /// Its byte offset in the file.
    pub offset: u64,
    /// Whether it is a chunk (whose messages are lost with it).
    pub chunk: bool,
    /// What is wrong.
    pub error: Error,
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
        let (file, meta) = crate::fs::open(path)?;
        if meta.len() < mcap::MAGIC.len() as u64 {
            return Err(Error::format(
                path,
                format!(
                    "not an MCAP file ({} bytes: shorter than its magic)",
                    meta.len()
                ),
            ));
        }
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
            chunk_at: 0,
        })
    }

    /// The next record of the data section, chunks opened: `None` at its end (or at the end of
    /// a file that breaks off between records, an unfinished recording). A chunk or record that
    /// cannot be read is [`Item::Damaged`] and the walk goes on after it; the error (naming the
    /// file and `context`) is for a framing that breaks off inside the file.
    pub fn next(&mut self, context: &dyn Fn() -> String) -> Result<Option<Item<'_>>> {
        let fail = |e: String| Error::format(&self.path, format!("{}: {e}", context()));
        let damaged = |at: usize, chunk, error| {
            Item::Damaged(Damage {
                offset: at as u64,
                chunk,
                error,
            })
        };
        loop {
            let at = self.chunk_at;
            match &mut self.chunk {
                Chunk::Plain(span) if span.start < span.end => {
                    let found = frame(&self.map[..span.end], span.start);
                    let Ok(Some((op, body, next))) = found else {
                        // Its CRC matched (or it has none), yet a record breaks off inside.
                        self.chunk = Chunk::None;
                        let e = fail(format!("a record breaks off inside the chunk at byte {at}"));
                        return Ok(Some(damaged(at, true, e)));
                    };
                    span.start = next;
                    return Ok(Some(match mcap::parse_record(op, body) {
                        Ok(r) => Item::Record(r),
                        Err(e) => damaged(at, false, Error::mcap(&self.path, context(), e)),
                    }));
                }
                Chunk::Unpacked(records) => {
                    if let Some(r) = records.next() {
                        return Ok(Some(Item::Record(r)));
                    }
                }
                _ => {}
            }
            self.chunk = Chunk::None;
            release(&self.map, &mut self.released, self.at);
            let Some((op, body, next)) = frame(&self.map, self.at).map_err(fail)? else {
                return Ok(None);
            };
            let record_at = self.at;
            self.at = next;
            let parsed = mcap::parse_record(op, body).map_err(|e| {
                let what = format!("{} (the record at byte {record_at})", context());
                Error::mcap(&self.path, what, e)
            });
            match (op, parsed) {
                (op::DATA_END | op::FOOTER, _) => {
                    self.at = self.map.len();
                    return Ok(None);
                }
                (op::CHUNK, Ok(r)) => match self.chunk(r, record_at, context) {
                    Ok(c) => (self.chunk, self.chunk_at) = (c, record_at),
                    Err(e) => return Ok(Some(damaged(record_at, true, e))),
                },
                (_, Ok(r)) => return Ok(Some(Item::Record(r))),
                (op, Err(e)) => return Ok(Some(damaged(record_at, op == op::CHUNK, e))),
            }
        }
    }

    /// Whether the next record is one of the file's own (not a chunk's) with opcode `op`.
    pub fn next_is(&self, op: u8) -> bool {
        let in_chunk = match &self.chunk {
            Chunk::None => false,
            Chunk::Plain(span) => span.start < span.end,
            Chunk::Unpacked(records) => records.len() > 0,
        };
        !in_chunk && self.map.get(self.at) == Some(&op)
    }

    /// The records of a chunk record (at byte `at`): where they lie when it is uncompressed (its
    /// CRC checked, where it has one: 0 means none, as the specification says), else
    /// decompressed (the library checks the CRC). An error when the CRC differs or the data
    /// does not decompress or parse.
    fn chunk(&self, record: Record<'_>, at: usize, context: &dyn Fn() -> String) -> Result<Chunk> {
        let Record::Chunk { header, data } = record else {
            unreachable!("a chunk record parses as a chunk");
        };
        let what = || format!("{} (the chunk at byte {at})", context());
        let mcap_err = |e| Error::mcap(&self.path, what(), e);
        if header.compression.is_empty() {
            if let std::borrow::Cow::Borrowed(d) = data {
                let saved = header.uncompressed_crc;
                if saved != 0 {
                    let calculated = crc32fast::hash(d);
                    if calculated != saved {
                        let e = mcap::McapError::BadChunkCrc { saved, calculated };
                        return Err(mcap_err(e));
                    }
                }
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
