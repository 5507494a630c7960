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
