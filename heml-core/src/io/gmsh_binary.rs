//! The binary encoding of Gmsh `.msh` files (file-type 1 in `$MeshFormat`), as
//! written by Gmsh (`-bin`) and by meshio (binary by default).
//!
//! Section keywords and, in version 2.2, the counts after `$Nodes` and
//! `$Elements` stay ASCII lines; the records are raw numbers: C `int` (4 bytes),
//! `double` (8 bytes) and, in version 4.1, `size_t` (the data-size of the
//! `$MeshFormat` line, 8 on every 64-bit machine). Byte order is the writer's:
//! the integer 1 written in binary right after the `$MeshFormat` line tells which
//! (`01 00 00 00` little-endian, `00 00 00 01` big-endian), so files from either
//! kind of machine read.
//!
//! Every count is checked against the bytes left in the file before anything is
//! reserved (a lying header cannot allocate more than the file could hold), and
//! every error names the line and the byte offset of the record that failed.

use super::cursor::Cursor;
use crate::error::Result;

/// Byte order and `size_t` width of one binary file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Binary {
    /// Whether numbers are stored least significant byte first.
    pub little_endian: bool,
    /// Bytes of a `size_t` (4 or 8; version 4.1 only).
    pub size_t: usize,
}

impl Binary {
    /// Reads the binary integer 1 that follows the `$MeshFormat` line and infers
    /// the writer's byte order from it.
    pub fn detect(c: &mut Cursor<'_>, size_t: usize) -> Result<Binary> {
        let off = c.offset();
        let b = Self::take_at(c, 4, "the binary integer 1 after the $MeshFormat line")?;
        let a = [b[0], b[1], b[2], b[3]];
        let little_endian = match (i32::from_le_bytes(a), i32::from_be_bytes(a)) {
            (1, _) => true,
            (_, 1) => false,
            _ => {
                return Err(c.err(format!(
                    "at byte {off}: expected the integer 1 written in binary (endianness check) after the \
                     $MeshFormat line of a binary file, found bytes {a:02x?}"
                )))
            }
        };
        Ok(Binary { little_endian, size_t })
    }

    fn take_at<'a>(c: &mut Cursor<'a>, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > c.remaining() {
            return Err(c.err(format!(
                "unexpected end of file at byte {} while reading {what}: {n} bytes needed, {} left (file truncated?)",
                c.offset(),
                c.remaining()
            )));
        }
        c.bytes(n, what)
    }

    /// The next `N` bytes in little-endian order.
    fn le<const N: usize>(&self, c: &mut Cursor<'_>, what: &str) -> Result<[u8; N]> {
        let b = Self::take_at(c, N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(b);
        if !self.little_endian {
            a.reverse();
        }
        Ok(a)
    }

    /// A C `int`.
    pub fn int(&self, c: &mut Cursor<'_>, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.le(c, what)?))
    }

    /// A `size_t` (4 or 8 bytes).
    pub fn size(&self, c: &mut Cursor<'_>, what: &str) -> Result<u64> {
        Ok(match self.size_t {
            4 => u64::from(u32::from_le_bytes(self.le(c, what)?)),
            _ => u64::from_le_bytes(self.le(c, what)?),
        })
    }

    /// A `double`.
    pub fn float(&self, c: &mut Cursor<'_>, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.le(c, what)?))
    }

    /// A non-negative `int` used as a count, a node or an element number.
    pub fn uint(&self, c: &mut Cursor<'_>, what: &str) -> Result<u64> {
        let off = c.offset();
        let v = self.int(c, what)?;
        u64::try_from(v).map_err(|_| c.err(format!("at byte {off}: {what} is {v}, expected a non-negative integer")))
    }

    /// A `size_t` count that must fit in memory.
    pub fn count(&self, c: &mut Cursor<'_>, what: &str) -> Result<usize> {
        let off = c.offset();
        let v = self.size(c, what)?;
        usize::try_from(v).map_err(|_| c.err(format!("at byte {off}: {what} {v} does not fit in memory")))
    }

    /// Fails unless `n` records of `each` bytes fit in what is left of the file:
    /// run before reserving or looping over `n`, so that an absurd count is a
    /// clear error instead of a huge allocation or a long loop.
    pub fn check_room(&self, c: &Cursor<'_>, n: usize, each: usize, what: &str) -> Result<()> {
        let need = n.checked_mul(each);
        if need.is_none_or(|b| b > c.remaining()) {
            return Err(c.err(format!(
                "at byte {}: {n} {what} need {} bytes of binary data, only {} are left (count wrong or file \
                 truncated?)",
                c.offset(),
                need.map_or_else(|| "more than addressable".to_string(), |b| b.to_string()),
                c.remaining()
            )));
        }
        Ok(())
    }
}
