//! The binary chunk, buffer views and accessors of the file, and the GLB container (glTF 2.0
//! specification, "Binary glTF Layout"): every buffer view starts on a 4-byte boundary (so every
//! accessor is aligned to its component size), the JSON chunk is padded with spaces and the
//! binary chunk with zeros to a multiple of 4.

use serde_json::{Value, json};

use crate::ExportError;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// The binary chunk under construction, with its buffer views and accessors.
#[derive(Default)]
pub(crate) struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

fn type_name(components: usize) -> &'static str {
    match components {
        1 => "SCALAR",
        2 => "VEC2",
        3 => "VEC3",
        4 => "VEC4",
        _ => "MAT4",
    }
}

impl Builder {
    /// A buffer view of `bytes` (aligned to 4), with `target` when vertex or index data.
    pub(crate) fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, view: usize, component: u32, count: usize, components: usize, extra: Value) -> usize {
        let mut a = json!({
            "bufferView": view,
            "componentType": component,
            "count": count,
            "type": type_name(components),
        });
        if let (Value::Object(a), Value::Object(extra)) = (&mut a, extra) {
            a.extend(extra);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A float accessor of `components` per element; `animation` data gets no buffer-view
    /// target; `bounds` adds `min`/`max` (required for `POSITION` and animation inputs).
    pub(crate) fn floats(&mut self, data: &[f32], components: usize, animation: bool, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, (!animation).then_some(ARRAY_BUFFER));
        let count = data.len() / components;
        let mut extra = json!({});
        if bounds {
            let mut lo = vec![f32::INFINITY; components];
            let mut hi = vec![f32::NEG_INFINITY; components];
            for e in data.chunks_exact(components) {
                for k in 0..components {
                    lo[k] = lo[k].min(e[k]);
                    hi[k] = hi[k].max(e[k]);
                }
            }
            extra = json!({ "min": lo, "max": hi });
        }
        self.accessor(view, FLOAT, count, components, extra)
    }

    /// `MAT4` float accessor (inverse bind matrices, column-major).
    pub(crate) fn mat4(&mut self, data: &[f32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessor(view, FLOAT, data.len() / 16, 16, json!({}))
    }

    /// `JOINTS_n` (`VEC4`): unsigned bytes when every bind fits, else unsigned shorts.
    pub(crate) fn joints(&mut self, joints: &[u16], bind_count: usize) -> usize {
        let (bytes, component): (Vec<u8>, u32) = if bind_count <= 256 {
            (joints.iter().map(|&j| j as u8).collect(), UNSIGNED_BYTE)
        } else {
            (joints.iter().flat_map(|j| j.to_le_bytes()).collect(), UNSIGNED_SHORT)
        };
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.accessor(view, component, joints.len() / 4, 4, json!({}))
    }

    /// Triangle indices: unsigned shorts when they fit, else unsigned ints.
    pub(crate) fn indices(&mut self, indices: &[u32]) -> usize {
        let max = indices.iter().copied().max().unwrap_or(0);
        let (bytes, component): (Vec<u8>, u32) = if max < u32::from(u16::MAX) {
            (indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(), UNSIGNED_SHORT)
        } else {
            (indices.iter().flat_map(|i| i.to_le_bytes()).collect(), UNSIGNED_INT)
        };
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.accessor(view, component, indices.len(), 1, json!({}))
    }

    /// The GLB file: `doc` with the buffer, views and accessors added, then the binary chunk.
    pub(crate) fn finish(mut self, mut doc: Value) -> Result<Vec<u8>, ExportError> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        if !self.bin.is_empty() {
            doc["buffers"] = json!([{ "byteLength": self.bin.len() }]);
            doc["bufferViews"] = Value::Array(std::mem::take(&mut self.views));
            doc["accessors"] = Value::Array(std::mem::take(&mut self.accessors));
        }
        let mut text = serde_json::to_vec(&doc).map_err(|e| ExportError::TooLarge(format!("JSON: {e}")))?;
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let total = 12 + 8 + text.len() + if self.bin.is_empty() { 0 } else { 8 + self.bin.len() };
        let total32 = u32::try_from(total)
            .map_err(|_| ExportError::TooLarge(format!("{total} bytes exceed the GLB's 4 GiB limit")))?;
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&total32.to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        if !self.bin.is_empty() {
            out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&self.bin);
        }
        Ok(out)
    }
}
