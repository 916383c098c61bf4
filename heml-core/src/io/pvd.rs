//! ParaView `.pvd` collections: a time series of frame files.
//!
//! The collection is rewritten (atomically) every time a frame is added, so a
//! simulation that is stopped at any moment leaves a valid `.pvd` listing exactly
//! the frames written so far, and ParaView can open it while the run goes on.

use std::io::Write;
use std::path::{Path, PathBuf};

use quick_xml::events::Event;
use quick_xml::Reader;

use super::atomic::write_atomic;
use super::vtu_write::xml_escape;
use crate::error::{HemlError, Result};

/// Writer of a `.pvd` file listing `(time, file)` pairs.
#[derive(Debug, Clone)]
pub struct PvdWriter {
    path: PathBuf,
    entries: Vec<(f64, String)>,
}

impl PvdWriter {
    /// Creates (or truncates to an empty collection) the `.pvd` at `path`.
    pub fn create(path: impl Into<PathBuf>) -> Result<Self> {
        let w = PvdWriter {
            path: path.into(),
            entries: Vec::new(),
        };
        w.flush()?;
        Ok(w)
    }

    /// The `.pvd` path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The `(time, file)` entries so far (files as written in the `.pvd`).
    pub fn entries(&self) -> &[(f64, String)] {
        &self.entries
    }

    /// Adds a frame and rewrites the collection. `file` is stored relative to the
    /// `.pvd`'s directory when it lies inside it (so the series can be moved).
    pub fn add(&mut self, time: f64, file: &Path) -> Result<()> {
        if !time.is_finite() {
            return Err(HemlError::Invalid(format!("pvd frame time must be finite, got {time}")));
        }
        let dir = self.path.parent().unwrap_or(Path::new(""));
        let rel = if dir.as_os_str().is_empty() {
            file
        } else {
            file.strip_prefix(dir).unwrap_or(file)
        };
        let name = rel
            .to_str()
            .ok_or_else(|| HemlError::Invalid(format!("frame path '{}' is not valid UTF-8", rel.display())))?;
        self.entries.push((time, name.replace('\\', "/")));
        self.flush()
    }

    fn flush(&self) -> Result<()> {
        write_atomic(&self.path, |w| {
            writeln!(w, "<?xml version=\"1.0\"?>")?;
            writeln!(
                w,
                "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
            )?;
            writeln!(w, "<Collection>")?;
            for (t, f) in &self.entries {
                writeln!(
                    w,
                    "<DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{}\"/>",
                    xml_escape(f)
                )?;
            }
            writeln!(w, "</Collection>\n</VTKFile>")
        })
    }
}

/// Reads the `(time, file)` entries of a `.pvd` (files as written, relative to the
/// `.pvd`'s directory when they were inside it).
pub fn read_pvd(path: &Path) -> Result<Vec<(f64, String)>> {
    let bytes = super::read_bytes(path)?;
    let perr = |pos: u64, msg: String| HemlError::Parse {
        file: path.to_path_buf(),
        line: super::cursor::line_of(&bytes, pos as usize),
        msg,
    };
    let mut reader = Reader::from_reader(bytes.as_slice());
    let mut out = Vec::new();
    loop {
        let ev = reader
            .read_event()
            .map_err(|e| perr(reader.error_position(), format!("malformed XML: {e}")))?;
        match ev {
            Event::Start(e) | Event::Empty(e) if e.local_name().as_ref() == b"DataSet" => {
                let pos = reader.buffer_position();
                let mut time = None;
                let mut file = None;
                for a in e.attributes() {
                    let a = a.map_err(|e| perr(pos, format!("bad attribute: {e}")))?;
                    let v = a
                        .unescape_value()
                        .map_err(|e| perr(pos, format!("bad attribute value: {e}")))?;
                    match a.key.as_ref() {
                        b"timestep" => {
                            time = Some(
                                v.trim()
                                    .parse::<f64>()
                                    .map_err(|_| perr(pos, format!("timestep '{v}' is not a number")))?,
                            )
                        }
                        b"file" => file = Some(v.into_owned()),
                        _ => {}
                    }
                }
                match (time, file) {
                    (Some(t), Some(f)) => out.push((t, f)),
                    _ => return Err(perr(pos, "DataSet without timestep or file".into())),
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(out)
}
