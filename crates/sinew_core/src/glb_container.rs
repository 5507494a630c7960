//! The binary glTF 2.0 container (`.glb`) and the buffer its accessors
//! read, shared by the character writer ([`crate::character::glb`]) and the
//! bake exporter ([`crate::bake`]).

use crate::mesh::vertex_normals;
use glam::Vec3;
use serde_json::{Value, json};

/// glTF component types and buffer-view targets.
pub(crate) const FLOAT: u32 = 5126;
pub(crate) const UNSIGNED_SHORT: u32 = 5123;
pub(crate) const UNSIGNED_INT: u32 = 5125;
pub(crate) const ARRAY_BUFFER: u32 = 34962;
pub(crate) const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The binary chunk under construction, with its views and accessors.
#[derive(Default)]
pub(crate) struct BinaryBuffer {
    pub(crate) bytes: Vec<u8>,
    pub(crate) views: Vec<Value>,
    pub(crate) accessors: Vec<Value>,
}

impl BinaryBuffer {
    /// Appends `data` as a buffer view (4-byte aligned) read by one accessor;
    /// returns the accessor's index.
    pub(crate) fn accessor(
        &mut self,
        data: Vec<u8>,
        target: Option<u32>,
        component_type: u32,
        count: usize,
        kind: &str,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bytes.len(),
            "byteLength": data.len(),
        });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bytes.extend(data);
        self.views.push(view);
        let mut accessor = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component_type,
            "count": count,
            "type": kind,
        });
        if let Some((min, max)) = bounds {
            accessor["min"] = json!(min);
            accessor["max"] = json!(max);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

impl BinaryBuffer {
    /// `positions` as a `POSITION` accessor (with the bounds glTF requires).
    pub(crate) fn positions(&mut self, positions: &[Vec3]) -> usize {
        let (lo, hi) = positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        self.accessor(
            floats(positions.iter().flat_map(|p| p.to_array())),
            Some(ARRAY_BUFFER),
            FLOAT,
            positions.len(),
            "VEC3",
            Some((lo.to_array().to_vec(), hi.to_array().to_vec())),
        )
    }

    /// Area-weighted unit vertex normals of `triangles` over `positions` as a
    /// `NORMAL` accessor; glTF wants unit length, so a vertex on no triangle
    /// gets +Y.
    pub(crate) fn normals(&mut self, triangles: &[[u32; 3]], positions: &[Vec3]) -> usize {
        let mut normals = Vec::new();
        vertex_normals(triangles, positions, &mut normals);
        for n in normals.iter_mut().filter(|n| **n == Vec3::ZERO) {
            *n = Vec3::Y;
        }
        self.accessor(
            floats(normals.iter().flat_map(|p| p.to_array())),
            Some(ARRAY_BUFFER),
            FLOAT,
            positions.len(),
            "VEC3",
            None,
        )
    }

    /// `triangles` as an index accessor (`u32`).
    pub(crate) fn indices(&mut self, triangles: &[[u32; 3]]) -> usize {
        let bytes = triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        self.accessor(
            bytes,
            Some(ELEMENT_ARRAY_BUFFER),
            UNSIGNED_INT,
            triangles.len() * 3,
            "SCALAR",
            None,
        )
    }
}

pub(crate) fn floats(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// The `.glb` container: header, JSON chunk (space-padded), BIN chunk
/// (zero-padded).
pub(crate) fn assemble(document: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut text = document.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(text);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// A `.glb` read back: the JSON document and the binary chunk.
pub(crate) struct GlbDocument {
    pub(crate) json: Value,
    pub(crate) bin: Vec<u8>,
}

impl GlbDocument {
    /// Splits a `.glb`'s bytes into its JSON and BIN chunks; the error says
    /// what is wrong with the container.
    pub(crate) fn parse(bytes: &[u8]) -> Result<Self, String> {
        let word = |at: usize| -> Result<u32, String> {
            bytes
                .get(at..at + 4)
                .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
                .ok_or_else(|| format!("truncated at byte {at} of {}", bytes.len()))
        };
        if bytes.get(..4) != Some(b"glTF") {
            return Err("not a binary glTF (no 'glTF' magic)".into());
        }
        if word(4)? != 2 {
            return Err(format!("glTF version {}, not 2", word(4)?));
        }
        let json_len = word(12)? as usize;
        if word(16)? != u32::from_le_bytes(*b"JSON") {
            return Err("the first chunk is not JSON".into());
        }
        let json_bytes = bytes
            .get(20..20 + json_len)
            .ok_or_else(|| format!("JSON chunk of {json_len} bytes runs past the file"))?;
        let json: Value =
            serde_json::from_slice(json_bytes).map_err(|e| format!("JSON chunk: {e}"))?;
        let at = 20 + json_len;
        let bin = if at + 8 <= bytes.len() {
            let len = word(at)? as usize;
            if word(at + 4)? != u32::from_le_bytes(*b"BIN\0") {
                return Err("the second chunk is not BIN".into());
            }
            bytes
                .get(at + 8..at + 8 + len)
                .ok_or_else(|| format!("BIN chunk of {len} bytes runs past the file"))?
                .to_vec()
        } else {
            Vec::new()
        };
        Ok(Self { json, bin })
    }

    /// Accessor `index` as `f64` components, `width` per element
    /// (normalised integers mapped to [0, 1] as glTF defines); the error
    /// names what is wrong.
    pub(crate) fn accessor(&self, index: usize, width: usize) -> Result<Vec<f64>, String> {
        let a = self
            .json
            .pointer(&format!("/accessors/{index}"))
            .ok_or_else(|| format!("accessor {index} does not exist"))?;
        let count = a["count"].as_u64().ok_or("accessor without a count")? as usize;
        let kind = a["type"].as_str().unwrap_or("");
        let expected = match width {
            1 => "SCALAR",
            2 => "VEC2",
            3 => "VEC3",
            4 => "VEC4",
            16 => "MAT4",
            _ => "",
        };
        if kind != expected {
            return Err(format!("accessor {index} is {kind}, expected {expected}"));
        }
        let component = a["componentType"].as_u64().unwrap_or(0);
        let (size, read): (usize, fn(&[u8]) -> f64) = match component {
            5126 => (4, |b| f32::from_le_bytes(b.try_into().expect("4")) as f64),
            5125 => (4, |b| u32::from_le_bytes(b.try_into().expect("4")) as f64),
            5123 => (2, |b| u16::from_le_bytes(b.try_into().expect("2")) as f64),
            5121 => (1, |b| b[0] as f64),
            other => return Err(format!("accessor {index}: component type {other} not read")),
        };
        let normalized = a["normalized"].as_bool().unwrap_or(false);
        let scale = match (normalized, component) {
            (true, 5121) => 1.0 / 255.0,
            (true, 5123) => 1.0 / 65535.0,
            _ => 1.0,
        };
        let Some(view) = a["bufferView"].as_u64() else {
            return Ok(vec![0.0; count * width]); // glTF: all zeros
        };
        let v = self
            .json
            .pointer(&format!("/bufferViews/{view}"))
            .ok_or_else(|| format!("accessor {index}: buffer view {view} does not exist"))?;
        if v["buffer"].as_u64().unwrap_or(0) != 0 || self.json.pointer("/buffers/0/uri").is_some() {
            return Err("external buffers are not read: embed them (a .glb's BIN chunk)".into());
        }
        let start = v["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let stride = v["byteStride"]
            .as_u64()
            .map_or(size * width, |s| s as usize);
        let mut out = Vec::with_capacity(count * width);
        for e in 0..count {
            for c in 0..width {
                let at = start + e * stride + c * size;
                let bytes = self
                    .bin
                    .get(at..at + size)
                    .ok_or_else(|| format!("accessor {index} runs past the binary chunk"))?;
                out.push(read(bytes) * scale);
            }
        }
        Ok(out)
    }
}
