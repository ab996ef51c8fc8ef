//! OMG CDR (XCDR1, ROS 2's default serialisation) as a byte cursor: a 4-byte encapsulation
//! header that names the byte order, then each primitive aligned to its own size, counted from
//! the end of that header. Only what ROS 2 messages need: integers, floats, strings and byte
//! sequences.

/// A cursor over one serialised message.
#[derive(Debug)]
pub(crate) struct Cdr<'a> {
    body: &'a [u8],
    at: usize,
    big_endian: bool,
}

/// What went wrong, as text for the caller to place (it knows the file and the message).
pub(crate) type CdrResult<T> = std::result::Result<T, String>;

impl<'a> Cdr<'a> {
    /// Reads the encapsulation header: `00 00` (CDR big-endian) or `00 01` (little-endian), then
    /// two option bytes.
    pub(crate) fn new(message: &'a [u8]) -> CdrResult<Cdr<'a>> {
        let Some((head, body)) = message.split_first_chunk::<4>() else {
            return Err(format!(
                "a message of {} bytes, too short for the CDR header",
                message.len()
            ));
        };
        let big_endian = match [head[0], head[1]] {
            [0, 0] => true,
            [0, 1] => false,
            other => {
                return Err(format!(
                    "encapsulation {other:02x?}: not plain CDR (00 00 or 00 01; XCDR2 and \
                     parameter lists are not ROS 2's default)"
                ))
            }
        };
        Ok(Cdr {
            body,
            at: 0,
            big_endian,
        })
    }

    /// The next `n` bytes, unaligned.
    fn take(&mut self, n: usize, what: &str) -> CdrResult<&'a [u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.body.len());
        let Some(end) = end else {
            return Err(format!(
                "the message ends inside {what} (needs {n} bytes at byte {}, has {})",
                self.at + 4,
                self.body.len() + 4
            ));
        };
        let s = &self.body[self.at..end];
        self.at = end;
        Ok(s)
    }

    /// The next `N`-byte primitive, aligned to `N`.
    fn prim<const N: usize>(&mut self, what: &str) -> CdrResult<[u8; N]> {
        self.at = self.at.next_multiple_of(N).min(self.body.len());
        let b = self.take(N, what)?;
        let mut a: [u8; N] = b.try_into().expect("took N bytes");
        if self.big_endian != cfg!(target_endian = "big") {
            a.reverse();
        }
        Ok(a)
    }

    /// A `uint8` (or `bool`, `char`).
    pub(crate) fn u8(&mut self, what: &str) -> CdrResult<u8> {
        Ok(self.take(1, what)?[0])
    }

    /// A `uint32`.
    pub(crate) fn u32(&mut self, what: &str) -> CdrResult<u32> {
        Ok(u32::from_ne_bytes(self.prim::<4>(what)?))
    }

    /// An `int32`.
    pub(crate) fn i32(&mut self, what: &str) -> CdrResult<i32> {
        Ok(i32::from_ne_bytes(self.prim::<4>(what)?))
    }

    /// A `float64`.
    pub(crate) fn f64(&mut self, what: &str) -> CdrResult<f64> {
        Ok(f64::from_ne_bytes(self.prim::<8>(what)?))
    }

    /// A `bool` (one byte, 0 or 1).
    pub(crate) fn bool(&mut self, what: &str) -> CdrResult<bool> {
        match self.u8(what)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(format!("{what} is {v}, not a bool (0 or 1)")),
        }
    }

    /// A `string`: a `uint32` length counting the terminating NUL, the bytes, the NUL.
    pub(crate) fn string(&mut self, what: &str) -> CdrResult<String> {
        let n = self.u32(what)? as usize;
        let b = self.take(n, what)?;
        let text = match b.split_last() {
            Some((0, text)) => text,
            None => b,
            Some(_) => return Err(format!("{what} has no terminating NUL")),
        };
        String::from_utf8(text.to_vec()).map_err(|_| format!("{what} is not UTF-8"))
    }

    /// A `uint8[]` sequence: a `uint32` length and the bytes, borrowed.
    pub(crate) fn bytes(&mut self, what: &str) -> CdrResult<&'a [u8]> {
        let n = self.u32(what)? as usize;
        self.take(n, what)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_aligned_primitives_in_either_byte_order() {
        // uint8 7, (pad 3), uint32 0x01020304, string "ab", uint32 9
        let le = [
            0, 1, 0, 0, 7, 0, 0, 0, 4, 3, 2, 1, 3, 0, 0, 0, b'a', b'b', 0, 0, 9, 0, 0, 0,
        ];
        let be = [
            0, 0, 0, 0, 7, 0, 0, 0, 1, 2, 3, 4, 0, 0, 0, 3, b'a', b'b', 0, 0, 0, 0, 0, 9,
        ];
        for (m, big) in [(&le[..], false), (&be[..], true)] {
            let mut c = Cdr::new(m).unwrap();
            assert_eq!(c.big_endian, big);
            assert_eq!(c.u8("a").unwrap(), 7);
            assert_eq!(c.u32("b").unwrap(), 0x01020304);
            assert_eq!(c.string("c").unwrap(), "ab");
            assert_eq!(c.u32("d").unwrap(), 9);
            let e = c.u32("the end").unwrap_err();
            assert!(e.contains("ends inside the end"), "{e}");
        }
    }

    #[test]
    fn refuses_other_encapsulations_and_short_messages() {
        assert!(Cdr::new(&[0, 1]).unwrap_err().contains("too short"));
        assert!(Cdr::new(&[0, 3, 0, 0])
            .unwrap_err()
            .contains("not plain CDR"));
        let mut c = Cdr::new(&[0, 1, 0, 0, 5, 0, 0, 0, b'a', b'b', b'c', b'd', b'e']).unwrap();
        assert!(c.string("name").unwrap_err().contains("NUL"));
        let mut c = Cdr::new(&[0, 1, 0, 0, 2]).unwrap();
        assert!(c.bool("flag").unwrap_err().contains("not a bool"));
    }
}
