//! The binary data encoding of VTK XML files: a size header (UInt32 or UInt64)
//! followed by the data, optionally compressed in blocks (zlib, or LZMA: each
//! block an `.xz` stream, as `vtkLZMADataCompressor` and meshio write them),
//! optionally base64 encoded. Shared by the `.vtu` reader and writer.
//!
//! Uncompressed: `[nbytes] data`. Compressed: `[nblocks, block_size,
//! last_block_size, csize_0 … csize_{n-1}]` then the compressed blocks, where a
//! `last_block_size` of 0 means the last block is full. Inline base64 data is
//! written by VTK with the header and the data encoded *separately* when
//! compressed (and jointly when not), so the decoder accepts both.

use std::io::Read;

use base64::engine::general_purpose::STANDARD;
use base64::Engine;

/// Width of the integers in the size header (`header_type` attribute).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HeaderType {
    U32,
    U64,
}

impl HeaderType {
    pub fn size(self) -> usize {
        match self {
            HeaderType::U32 => 4,
            HeaderType::U64 => 8,
        }
    }
}

/// The block compression of a file (`compressor` attribute of `<VTKFile>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Compressor {
    /// No compression: one size word, then the data.
    None,
    /// `vtkZLibDataCompressor`: zlib streams.
    Zlib,
    /// `vtkLZMADataCompressor`: `.xz` streams, decoded by the pure-Rust
    /// `lzma-rust2` crate.
    Lzma,
}

/// Most memory one LZMA block's decoder may take (KiB): a header may declare a
/// dictionary of up to 4 GiB, which the decoder would allocate before reading
/// a byte. 64 MiB is the dictionary of `xz -9`, the largest preset (VTK and
/// meshio use 8 MiB), plus the decoder's own tables.
const LZMA_MEM_LIMIT_KIB: u32 = 65 * 1024;

/// How the decoder reads numbers (byte order of the file).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Layout {
    pub header: HeaderType,
    pub little_endian: bool,
    pub compressor: Compressor,
}

impl Layout {
    fn word(&self, b: &[u8]) -> Option<usize> {
        let v = match self.header {
            HeaderType::U32 => {
                let a: [u8; 4] = b.get(..4)?.try_into().ok()?;
                u64::from(if self.little_endian {
                    u32::from_le_bytes(a)
                } else {
                    u32::from_be_bytes(a)
                })
            }
            HeaderType::U64 => {
                let a: [u8; 8] = b.get(..8)?.try_into().ok()?;
                if self.little_endian {
                    u64::from_le_bytes(a)
                } else {
                    u64::from_be_bytes(a)
                }
            }
        };
        usize::try_from(v).ok()
    }

    /// Decodes header + data from raw bytes; returns the data bytes and how many
    /// input bytes were used.
    ///
    /// `expected` is the size the data must have (from the Piece's counts): the
    /// sizes declared in the header are checked against it *before* anything is
    /// allocated or inflated, so a lying header (a "zlib bomb" whose 2 MB of
    /// compressed zeros declare 2 GiB for 181 points) fails at once. Each block
    /// is then inflated through `take`, bounded by its declared size.
    pub fn decode_raw(&self, b: &[u8], expected: usize) -> Result<(Vec<u8>, usize), String> {
        let h = self.header.size();
        let short = || "binary data is shorter than its header announces".to_string();
        let mismatch = |declared: &dyn std::fmt::Display| {
            format!("the block header declares {declared} bytes of data, expected {expected}")
        };
        if self.compressor == Compressor::None {
            let n = self.word(b).ok_or_else(short)?;
            if n != expected {
                return Err(mismatch(&n));
            }
            let end = h.checked_add(n).ok_or_else(short)?;
            let data = b.get(h..end).ok_or_else(short)?;
            return Ok((data.to_vec(), end));
        }
        let nblocks = self.word(b).ok_or_else(short)?;
        let bs = self.word(b.get(h..).unwrap_or_default()).ok_or_else(short)?;
        let last = self.word(b.get(2 * h..).unwrap_or_default()).ok_or_else(short)?;
        let header_len = nblocks
            .checked_add(3)
            .and_then(|k| k.checked_mul(h))
            .ok_or_else(short)?;
        if header_len > b.len() {
            return Err(short());
        }
        if last > bs {
            return Err(format!(
                "corrupt compression header: last block of {last} bytes is larger than the block size {bs}"
            ));
        }
        // total = (nblocks − 1)·bs + last, where last = 0 means a full last block
        let declared: u128 = match nblocks {
            0 => 0,
            n => (n as u128 - 1) * bs as u128 + if last == 0 { bs } else { last } as u128,
        };
        if declared != expected as u128 {
            return Err(mismatch(&declared));
        }
        let mut out = Vec::new();
        let mut pos = header_len;
        for k in 0..nblocks {
            let csize = self.word(&b[(3 + k) * h..]).ok_or_else(short)?;
            let end = pos.checked_add(csize).ok_or_else(short)?;
            let block = b.get(pos..end).ok_or_else(short)?;
            let want = if k + 1 == nblocks && last != 0 { last } else { bs };
            let before = out.len();
            // `take` bounds the output: a corrupt or hostile block cannot inflate
            // beyond the size its header declares (checked above against `expected`).
            let (name, r) = match self.compressor {
                Compressor::Lzma => (
                    "lzma",
                    lzma_rust2::XzReader::new_mem_limit(block, false, LZMA_MEM_LIMIT_KIB)
                        .take(want as u64 + 1)
                        .read_to_end(&mut out),
                ),
                _ => (
                    "zlib",
                    flate2::read::ZlibDecoder::new(block)
                        .take(want as u64 + 1)
                        .read_to_end(&mut out),
                ),
            };
            r.map_err(|e| match e.kind() {
                std::io::ErrorKind::OutOfMemory => format!(
                    "{name} block {k} declares a dictionary needing more than {} MiB to decompress \
                     (corrupt header?)",
                    LZMA_MEM_LIMIT_KIB / 1024
                ),
                _ => format!("{name} block {k} cannot be decompressed: {e}"),
            })?;
            if out.len() - before != want {
                return Err(format!(
                    "{name} block {k} decompresses to {} bytes, its header says {want}",
                    out.len() - before
                ));
            }
            pos = end;
        }
        Ok((out, pos))
    }

    /// Decodes base64 text (whitespace allowed) holding header + data of
    /// `expected` bytes (see [`Layout::decode_raw`]).
    pub fn decode_base64(&self, text: &[u8], expected: usize) -> Result<Vec<u8>, String> {
        let clean: Vec<u8> = text.iter().copied().filter(|b| !b.is_ascii_whitespace()).collect();
        // Jointly encoded (or separately encoded without padding in between): when
        // the whole text decodes, its header is the real one and its error stands.
        let joint_error = match STANDARD.decode(&clean) {
            Ok(all) => match self.decode_raw(&all, expected) {
                Ok((data, _)) => return Ok(data),
                Err(e) => Some(e),
            },
            Err(_) => None,
        };
        self.decode_separate(&clean, expected)
            .map_err(|e| joint_error.unwrap_or(e))
    }

    /// Base64 with the header encoded on its own (VTK's compressed inline form).
    fn decode_separate(&self, clean: &[u8], expected: usize) -> Result<Vec<u8>, String> {
        let h = self.header.size();
        let header_len = if self.compressor != Compressor::None {
            // the first 3 words are 3h bytes = 4h base64 characters, a whole number of groups
            let first = clean.get(..4 * h).ok_or("base64 data too short for its header")?;
            let first = STANDARD.decode(first).map_err(|e| format!("invalid base64: {e}"))?;
            let nblocks = self.word(&first).ok_or("base64 data too short for its header")?;
            nblocks
                .checked_add(3)
                .and_then(|k| k.checked_mul(h))
                .ok_or("corrupt header")?
        } else {
            h
        };
        let split = header_len.div_ceil(3).checked_mul(4).ok_or("corrupt header")?;
        let head = clean.get(..split).ok_or("base64 data too short for its header")?;
        let mut raw = STANDARD
            .decode(head)
            .map_err(|e| format!("invalid base64 in the header: {e}"))?;
        raw.extend(
            STANDARD
                .decode(&clean[split..])
                .map_err(|e| format!("invalid base64: {e}"))?,
        );
        self.decode_raw(&raw, expected).map(|(d, _)| d)
    }
}

/// Encodes `data` for an inline binary DataArray (UInt64 header), optionally
/// zlib-compressed in 32 KiB blocks.
pub(crate) fn encode_base64(data: &[u8], compress: bool) -> String {
    if !compress {
        let mut raw = Vec::with_capacity(8 + data.len());
        raw.extend_from_slice(&(data.len() as u64).to_le_bytes());
        raw.extend_from_slice(data);
        return STANDARD.encode(raw);
    }
    const BLOCK: usize = 1 << 15;
    let blocks: Vec<&[u8]> = data.chunks(BLOCK).collect();
    let compressed: Vec<Vec<u8>> = blocks
        .iter()
        .map(|b| {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            // writing into a Vec cannot fail
            let _ = std::io::Write::write_all(&mut e, b);
            e.finish().unwrap_or_default()
        })
        .collect();
    let mut header = Vec::new();
    for w in [blocks.len(), BLOCK, blocks.last().map_or(0, |b| b.len())] {
        header.extend_from_slice(&(w as u64).to_le_bytes());
    }
    for c in &compressed {
        header.extend_from_slice(&(c.len() as u64).to_le_bytes());
    }
    let body: Vec<u8> = compressed.concat();
    let mut s = STANDARD.encode(header);
    s.push_str(&STANDARD.encode(body));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trip_plain_and_zlib() {
        let data: Vec<u8> = (0..100_000u32).flat_map(|i| (i % 251).to_le_bytes()).collect();
        for compress in [false, true] {
            let s = encode_base64(&data, compress);
            let layout = Layout {
                header: HeaderType::U64,
                little_endian: true,
                compressor: if compress { Compressor::Zlib } else { Compressor::None },
            };
            assert_eq!(layout.decode_base64(s.as_bytes(), data.len()).unwrap(), data);
            // any other expected size is refused from the header alone
            let e = layout.decode_base64(s.as_bytes(), data.len() - 1).unwrap_err();
            assert!(e.contains(&format!("declares {} bytes", data.len())), "{e}");
        }
    }

    #[test]
    fn corrupt_data_is_an_error_not_a_panic() {
        let layout = Layout {
            header: HeaderType::U32,
            little_endian: true,
            compressor: Compressor::Zlib,
        };
        assert!(layout.decode_base64(b"AQAAAACAAAD4EAAA+Q8AAA==eJw9", 4344).is_err());
        assert!(layout.decode_base64(b"!!!!", 8).is_err());
        assert!(layout.decode_raw(&[255, 255, 255, 255, 0, 0], 8).is_err());
    }
}
