//! Bounds-checked accessor reading. Every offset, stride and count is checked with checked
//! arithmetic against the buffer view and the loaded buffer before a byte is read, so a lying
//! accessor becomes an [`ImportError::Accessor`] instead of a panic or a huge allocation (the
//! `gltf` crate's own reader slices without these checks). Handles strided views, accessors
//! without a buffer view (zeros), sparse substitution and normalized integers (glTF 2.0 §3.6.2,
//! §3.11 "normalized" conversion).

use std::path::Path;

use gltf::json;
use gltf::json::accessor::{ComponentType, GenericComponentType, IndexComponentType, Type};
use gltf::json::mesh::Semantic;
use gltf::json::validation::Checked;

use crate::limits::MAX_ACCESSOR_ELEMENTS;
use crate::{ImportError, PrimitiveRef};

/// What an accessor read needs to find its data and name itself in errors.
pub(crate) struct AccessorReader<'a> {
    pub root: &'a json::Root,
    pub buffers: &'a [Vec<u8>],
    pub file: &'a Path,
    pub at: &'a PrimitiveRef,
}

/// An accessor's elements converted to `f64` (normalized integers mapped to `[0, 1]`/`[-1, 1]`).
pub(crate) struct Elements {
    /// Components per element (1 for SCALAR … 4 for VEC4).
    pub components: usize,
    /// `count × components` values, element-major.
    pub values: Vec<f64>,
}

impl Elements {
    pub fn count(&self) -> usize {
        self.values.len() / self.components.max(1)
    }

    pub fn get(&self, element: usize) -> &[f64] {
        &self.values[element * self.components..(element + 1) * self.components]
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn decode(ct: ComponentType, b: &[u8]) -> f64 {
    match ct {
        ComponentType::I8 => f64::from(b[0] as i8),
        ComponentType::U8 => f64::from(b[0]),
        ComponentType::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
        ComponentType::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
        ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        ComponentType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
    }
}

fn normalize(ct: ComponentType, v: f64) -> f64 {
    match ct {
        ComponentType::I8 => (v / 127.0).max(-1.0),
        ComponentType::U8 => v / 255.0,
        ComponentType::I16 => (v / 32767.0).max(-1.0),
        ComponentType::U16 => v / 65535.0,
        ComponentType::U32 => v / f64::from(u32::MAX),
        ComponentType::F32 => v,
    }
}

impl AccessorReader<'_> {
    fn error(&self, attribute: &str, accessor: usize, message: String) -> ImportError {
        ImportError::Accessor {
            file: self.file.to_path_buf(),
            at: self.at.clone(),
            attribute: attribute.to_string(),
            accessor,
            message,
        }
    }

    /// Returns the bytes of buffer view `view` after checking it lies inside its buffer.
    fn view_bytes(&self, attribute: &str, accessor: usize, view: usize) -> Result<(&[u8], Option<u64>), ImportError> {
        let v = self
            .root
            .buffer_views
            .get(view)
            .ok_or_else(|| self.error(attribute, accessor, format!("buffer view {view} does not exist")))?;
        let buffer = self.buffers.get(v.buffer.value()).ok_or_else(|| {
            self.error(attribute, accessor, format!("buffer view {view} names missing buffer {}", v.buffer.value()))
        })?;
        let start = v.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(v.byte_length.0).filter(|&e| e <= buffer.len() as u64).ok_or_else(|| {
            self.error(
                attribute,
                accessor,
                format!(
                    "buffer view {view} (offset {start}, length {}) runs past its buffer's {} bytes",
                    v.byte_length.0,
                    buffer.len()
                ),
            )
        })?;
        Ok((&buffer[start as usize..end as usize], v.byte_stride.map(|s| s.0 as u64)))
    }

    /// Reads accessor `index` used as `attribute`, which must have one of the `allowed` types.
    pub fn read(&self, attribute: &str, index: usize, allowed: &[Type]) -> Result<Elements, ImportError> {
        let err = |m: String| self.error(attribute, index, m);
        let acc = self.root.accessors.get(index).ok_or_else(|| err("the accessor does not exist".to_string()))?;
        let ty = match acc.type_ {
            Checked::Valid(t) if allowed.contains(&t) => t,
            Checked::Valid(t) => {
                let names: Vec<&str> = allowed.iter().map(|&t| type_name(t)).collect();
                return Err(err(format!("type {} (expected {})", type_name(t), names.join(" or "))));
            }
            Checked::Invalid => return Err(err("invalid accessor type".to_string())),
        };
        let ct = match acc.component_type {
            Checked::Valid(GenericComponentType(ct)) => ct,
            Checked::Invalid => return Err(err("invalid component type".to_string())),
        };
        let count = acc.count.0;
        if count > MAX_ACCESSOR_ELEMENTS {
            return Err(ImportError::TooLarge {
                file: self.file.to_path_buf(),
                what: format!("{} ({attribute}): the element count of accessor {index}", self.at),
                count,
                limit: MAX_ACCESSOR_ELEMENTS,
            });
        }
        let count = count as usize;
        let components = ty.multiplicity();
        let comp_size = ct.size();
        let elem_size = (components * comp_size) as u64;
        let mut values = vec![0.0f64; count * components];

        if let Some(view) = acc.buffer_view {
            let (bytes, stride) = self.view_bytes(attribute, index, view.value())?;
            let stride = stride.unwrap_or(elem_size);
            if stride < elem_size {
                return Err(err(format!("byte stride {stride} is smaller than the element size {elem_size}")));
            }
            let offset = acc.byte_offset.map_or(0, |o| o.0);
            if count > 0 {
                let end = stride
                    .checked_mul(count as u64 - 1)
                    .and_then(|s| s.checked_add(offset))
                    .and_then(|s| s.checked_add(elem_size))
                    .filter(|&e| e <= bytes.len() as u64);
                if end.is_none() {
                    return Err(err(format!(
                        "{count} elements of {elem_size} bytes (stride {stride}, offset {offset}) do not fit in \
                         buffer view {} ({} bytes)",
                        view.value(),
                        bytes.len()
                    )));
                }
            }
            // Bounds checked above: every element lies inside `bytes`.
            for i in 0..count {
                let base = offset as usize + i * stride as usize;
                for c in 0..components {
                    let at = base + c * comp_size;
                    values[i * components + c] = decode(ct, &bytes[at..at + comp_size]);
                }
            }
        }

        if let Some(sparse) = &acc.sparse {
            let n = sparse.count.0;
            if n > count as u64 {
                return Err(err(format!("sparse count {n} exceeds the accessor count {count}")));
            }
            let n = n as usize;
            let ict = match sparse.indices.component_type {
                Checked::Valid(IndexComponentType(ct)) => ct,
                Checked::Invalid => return Err(err("invalid sparse index component type".to_string())),
            };
            let (ibytes, _) = self.view_bytes(attribute, index, sparse.indices.buffer_view.value())?;
            let (vbytes, _) = self.view_bytes(attribute, index, sparse.values.buffer_view.value())?;
            let isize = ict.size();
            let ioff = sparse.indices.byte_offset.0;
            let voff = sparse.values.byte_offset.0;
            let fits = |off: u64, each: u64, len: usize| {
                each.checked_mul(n as u64).and_then(|b| b.checked_add(off)).is_some_and(|e| e <= len as u64)
            };
            if !fits(ioff, isize as u64, ibytes.len()) || !fits(voff, elem_size, vbytes.len()) {
                return Err(err(format!("sparse indices/values ({n} entries) run past their buffer views")));
            }
            for k in 0..n {
                let at = ioff as usize + k * isize;
                let target = decode(ict, &ibytes[at..at + isize]) as usize;
                if target >= count {
                    return Err(err(format!("sparse index {target} is out of range (count {count})")));
                }
                for c in 0..components {
                    let at = voff as usize + k * elem_size as usize + c * comp_size;
                    values[target * components + c] = decode(ct, &vbytes[at..at + comp_size]);
                }
            }
        }

        if acc.normalized {
            for v in &mut values {
                *v = normalize(ct, *v);
            }
        }
        Ok(Elements { components, values })
    }

    /// Reads an index accessor: SCALAR of unsigned byte/short/int, not normalized.
    pub fn read_indices(&self, index: usize) -> Result<Vec<u32>, ImportError> {
        let acc = self
            .root
            .accessors
            .get(index)
            .ok_or_else(|| self.error("indices", index, "the accessor does not exist".to_string()))?;
        match acc.component_type {
            Checked::Valid(GenericComponentType(ComponentType::U8 | ComponentType::U16 | ComponentType::U32))
                if !acc.normalized => {}
            _ => {
                return Err(self.error(
                    "indices",
                    index,
                    "indices must be unsigned byte, short or int and not normalized".to_string(),
                ));
            }
        }
        let e = self.read("indices", index, &[Type::Scalar])?;
        Ok(e.values.into_iter().map(|v| v as u32).collect())
    }
}

/// The string a glTF file uses for a semantic (`POSITION`, `COLOR_0`, `_FUR`).
pub(crate) fn semantic_name(s: &Semantic) -> String {
    match s {
        Semantic::Positions => "POSITION".to_string(),
        Semantic::Normals => "NORMAL".to_string(),
        Semantic::Tangents => "TANGENT".to_string(),
        Semantic::Colors(n) => format!("COLOR_{n}"),
        Semantic::TexCoords(n) => format!("TEXCOORD_{n}"),
        Semantic::Joints(n) => format!("JOINTS_{n}"),
        Semantic::Weights(n) => format!("WEIGHTS_{n}"),
        Semantic::Extras(name) => format!("_{name}"),
    }
}
