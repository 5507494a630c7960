//! `.pc2` point caches: the vertex positions of one mesh, frame after frame,
//! as Maya, 3ds Max, Houdini and Blender (the Mesh Cache modifier) read them.
//!
//! Layout (little-endian): the 12-byte signature `POINTCACHE2\0`, `i32`
//! version (1), `i32` point count, `f32` start frame, `f32` sample rate
//! (frames between samples), `i32` sample count; then every sample's points
//! as `f32` x, y, z.

use super::BakeError;
use glam::Vec3;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The signature that opens every `.pc2` file.
pub const SIGNATURE: &[u8; 12] = b"POINTCACHE2\0";
/// Bytes before the first sample.
pub const HEADER_LEN: u64 = 32;
/// Byte offset of the sample count in the header.
const SAMPLE_COUNT_OFFSET: u64 = 28;

/// Writes a `.pc2` file one sample at a time; [`Pc2Writer::finish`] stores
/// the number of samples written in the header.
#[derive(Debug)]
pub struct Pc2Writer {
    file: BufWriter<File>,
    path: PathBuf,
    points: usize,
    samples: u32,
}

impl Pc2Writer {
    /// Starts `path` for `points` points per sample, the first sample at
    /// frame `start_frame`, one sample every `sample_rate` frames. The
    /// samples go to `<path>.partial`, renamed to `path` by
    /// [`Pc2Writer::finish`].
    pub fn create(
        path: &Path,
        points: usize,
        start_frame: f32,
        sample_rate: f32,
    ) -> Result<Self, BakeError> {
        let io = |source| BakeError::Io {
            file: path.to_path_buf(),
            source,
        };
        let count = i32::try_from(points).map_err(|_| BakeError::Invalid {
            file: path.to_path_buf(),
            element: "point count".into(),
            reason: format!("{points} points do not fit a .pc2 header"),
        })?;
        // Written as `<name>.partial` and renamed by `finish`: an interrupted
        // bake never leaves a cache that looks complete.
        let partial = crate::atomic_file::partial_path(path);
        let mut file = BufWriter::new(File::create(&partial).map_err(io)?);
        let mut header = Vec::with_capacity(HEADER_LEN as usize);
        header.extend(SIGNATURE);
        header.extend(1i32.to_le_bytes());
        header.extend(count.to_le_bytes());
        header.extend(start_frame.to_le_bytes());
        header.extend(sample_rate.to_le_bytes());
        header.extend(0i32.to_le_bytes());
        file.write_all(&header).map_err(io)?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
            points,
            samples: 0,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one sample; `positions` must hold exactly the point count.
    pub fn write_sample(&mut self, positions: &[Vec3]) -> Result<(), BakeError> {
        if positions.len() != self.points {
            return Err(BakeError::Invalid {
                file: self.path.clone(),
                element: format!("sample {}", self.samples),
                reason: format!(
                    "{} points, the cache holds {}",
                    positions.len(),
                    self.points
                ),
            });
        }
        let bytes: Vec<u8> = positions
            .iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        self.file
            .write_all(&bytes)
            .map_err(|source| BakeError::Io {
                file: self.path.clone(),
                source,
            })?;
        self.samples += 1;
        Ok(())
    }

    /// Stores the sample count in the header and closes the file; returns
    /// the number of samples.
    pub fn finish(mut self) -> Result<u32, BakeError> {
        let io = |source| BakeError::Io {
            file: self.path.clone(),
            source,
        };
        self.file.flush().map_err(io)?;
        let file = self.file.get_mut();
        file.seek(SeekFrom::Start(SAMPLE_COUNT_OFFSET))
            .map_err(io)?;
        file.write_all(&(self.samples as i32).to_le_bytes())
            .map_err(io)?;
        file.sync_all().map_err(io)?;
        std::fs::rename(crate::atomic_file::partial_path(&self.path), &self.path).map_err(io)?;
        Ok(self.samples)
    }
}

/// A `.pc2` file read back.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCache {
    /// Frame of the first sample.
    pub start_frame: f32,
    /// Frames between samples.
    pub sample_rate: f32,
    /// Per sample, the positions of every point.
    pub samples: Vec<Vec<Vec3>>,
}

/// Reads a `.pc2` file, checking its signature and that its size matches
/// its header.
pub fn read(path: &Path) -> Result<PointCache, BakeError> {
    let mut bytes = Vec::new();
    File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|source| BakeError::Io {
            file: path.to_path_buf(),
            source,
        })?;
    let invalid = |element: &str, reason: String| BakeError::Invalid {
        file: path.to_path_buf(),
        element: element.into(),
        reason,
    };
    if bytes.len() < HEADER_LEN as usize || &bytes[..12] != SIGNATURE {
        return Err(invalid(
            "header",
            "not a .pc2 file (no POINTCACHE2 signature)".into(),
        ));
    }
    let word = |at: usize| <[u8; 4]>::try_from(&bytes[at..at + 4]).expect("4 bytes");
    let (points, samples) = (i32::from_le_bytes(word(16)), i32::from_le_bytes(word(28)));
    let (Ok(points), Ok(samples)) = (usize::try_from(points), usize::try_from(samples)) else {
        return Err(invalid(
            "header",
            format!("negative counts: {points} points, {samples} samples"),
        ));
    };
    let expected = points
        .checked_mul(samples)
        .and_then(|n| n.checked_mul(12))
        .and_then(|n| n.checked_add(HEADER_LEN as usize));
    if expected != Some(bytes.len()) {
        return Err(invalid(
            "size",
            format!(
                "{} bytes, the header ({points} points × {samples} samples) says {}",
                bytes.len(),
                expected.map_or_else(|| "more than fits".into(), |n| n.to_string())
            ),
        ));
    }
    let floats: Vec<f32> = bytes[HEADER_LEN as usize..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    let samples = if points == 0 {
        vec![Vec::new(); samples]
    } else {
        floats
            .chunks_exact(points * 3)
            .map(|sample| {
                sample
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2]))
                    .collect()
            })
            .collect()
    };
    Ok(PointCache {
        start_frame: f32::from_le_bytes(word(20)),
        sample_rate: f32::from_le_bytes(word(24)),
        samples,
    })
}
