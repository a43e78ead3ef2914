//! The record layout shared by every typed section: a small self-describing table of typed
//! arrays plus a bincode-encoded metadata block. One parser validates every array's type, offset,
//! count and alignment once; typed section decoders then read arrays without re-checking bounds
//! (and without copying, when the payload is 16-byte aligned as it is inside a container).
//!
//! ```text
//! offset 0   u32 meta_len
//! offset 4   u32 array_count
//! offset 8   array_count × { u32 elem_type, u32 reserved = 0, u64 offset, u64 count }
//! then       meta_len bytes of metadata (bincode 2, little-endian, fixed-width integers)
//! then       the arrays, each at its 16-byte-aligned offset (relative to the payload start)
//! ```

use std::borrow::Cow;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::{FormatError, Result};

/// Element type codes of record arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ElemType {
    /// `u8`
    U8 = 1,
    /// `i8`
    I8 = 2,
    /// `u16`
    U16 = 3,
    /// `i16`
    I16 = 4,
    /// `u32`
    U32 = 5,
    /// `i32`
    I32 = 6,
    /// `f32` (IEEE 754 binary32)
    F32 = 7,
    /// IEEE 754 binary16, stored as its `u16` bit pattern
    F16 = 8,
    /// `u64`
    U64 = 9,
}

impl ElemType {
    fn from_code(code: u32) -> Option<ElemType> {
        Some(match code {
            1 => ElemType::U8,
            2 => ElemType::I8,
            3 => ElemType::U16,
            4 => ElemType::I16,
            5 => ElemType::U32,
            6 => ElemType::I32,
            7 => ElemType::F32,
            8 => ElemType::F16,
            9 => ElemType::U64,
            _ => return None,
        })
    }

    /// Size of one element in bytes.
    pub fn size(self) -> usize {
        match self {
            ElemType::U8 | ElemType::I8 => 1,
            ElemType::U16 | ElemType::I16 | ElemType::F16 => 2,
            ElemType::U32 | ElemType::I32 | ElemType::F32 => 4,
            ElemType::U64 => 8,
        }
    }
}

/// A plain-old-data element type that can be stored in a record array.
pub trait Element: bytemuck::Pod {
    /// The element type code written for this Rust type.
    const TYPE: ElemType;
}

macro_rules! element {
    ($($t:ty => $e:ident),*) => { $(impl Element for $t { const TYPE: ElemType = ElemType::$e; })* };
}
element!(u8 => U8, i8 => I8, u16 => U16, i16 => I16, u32 => U32, i32 => I32, f32 => F32, u64 => U64);

const ARRAY_ENTRY: usize = 24;
/// Upper bound on decoded metadata size: a lying length prefix inside the metadata cannot make the
/// decoder allocate more than this.
const META_LIMIT: usize = 1 << 20;

fn bincode_config() -> impl bincode::config::Config {
    bincode::config::standard().with_little_endian().with_fixed_int_encoding().with_limit::<META_LIMIT>()
}

/// Builds one record payload.
pub struct RecordWriter {
    meta: Vec<u8>,
    arrays: Vec<(ElemType, u64, Vec<u8>)>,
}

impl RecordWriter {
    /// Starts a record whose metadata block is `meta`.
    pub fn new(meta: &impl Serialize) -> Self {
        let meta = bincode::serde::encode_to_vec(meta, bincode_config())
            .expect("metadata structs are plain serde structs that bincode can always encode");
        RecordWriter { meta, arrays: Vec::new() }
    }

    /// Appends an array of elements.
    pub fn array<T: Element>(mut self, data: &[T]) -> Self {
        self.arrays.push((T::TYPE, data.len() as u64, bytemuck::cast_slice(data).to_vec()));
        self
    }

    /// Appends an array of IEEE binary16 values given as their bit patterns.
    pub fn array_f16_bits(mut self, bits: &[u16]) -> Self {
        self.arrays.push((ElemType::F16, bits.len() as u64, bytemuck::cast_slice(bits).to_vec()));
        self
    }

    /// The payload bytes.
    pub fn finish(self) -> Vec<u8> {
        let head = 8 + ARRAY_ENTRY * self.arrays.len();
        let mut cursor = head + self.meta.len();
        let mut offsets = Vec::with_capacity(self.arrays.len());
        for (_, _, bytes) in &self.arrays {
            cursor = cursor.div_ceil(16) * 16;
            offsets.push(cursor);
            cursor += bytes.len();
        }
        let mut out = vec![0u8; cursor];
        out[0..4].copy_from_slice(&(self.meta.len() as u32).to_le_bytes());
        out[4..8].copy_from_slice(&(self.arrays.len() as u32).to_le_bytes());
        for (i, ((ty, count, bytes), off)) in self.arrays.iter().zip(&offsets).enumerate() {
            let e = 8 + i * ARRAY_ENTRY;
            out[e..e + 4].copy_from_slice(&(*ty as u32).to_le_bytes());
            out[e + 8..e + 16].copy_from_slice(&(*off as u64).to_le_bytes());
            out[e + 16..e + 24].copy_from_slice(&count.to_le_bytes());
            out[*off..*off + bytes.len()].copy_from_slice(bytes);
        }
        out[head..head + self.meta.len()].copy_from_slice(&self.meta);
        out
    }
}

#[derive(Clone, Copy, Debug)]
struct ArrayRef {
    ty: ElemType,
    start: usize,
    count: usize,
}

/// Where a record's metadata lies, from the record's 8-byte head alone (`meta_len: u32`,
/// `array_count: u32`): `(offset from the payload start, length)`. Fails when the array table and
/// the metadata do not fit in a payload of `payload_len` bytes. [`Record::parse`] reads the same
/// head; this is for readers that peek at a section's first metadata field without reading it.
pub fn meta_span(head: [u8; 8], payload_len: u64) -> Result<(u64, u64)> {
    let meta_len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as u64;
    let array_count = u32::from_le_bytes([head[4], head[5], head[6], head[7]]) as u64;
    let meta_at = 8 + array_count * ARRAY_ENTRY as u64;
    match meta_at.checked_add(meta_len) {
        Some(end) if end <= payload_len => Ok((meta_at, meta_len)),
        _ => Err(FormatError::invalid_at(
            0,
            format!("metadata of {meta_len} bytes after {array_count} arrays does not fit in {payload_len} bytes"),
        )),
    }
}

/// A validated view of one record payload.
pub struct Record<'a> {
    bytes: &'a [u8],
    meta: &'a [u8],
    arrays: Vec<ArrayRef>,
}

impl<'a> Record<'a> {
    /// Validates the layout of `bytes`: the array table, every array's bounds and alignment, and
    /// the metadata bounds. Offsets in errors are relative to the payload start.
    pub fn parse(bytes: &'a [u8]) -> Result<Record<'a>> {
        if bytes.len() < 8 {
            return Err(FormatError::invalid_at(
                0,
                format!("record of {} bytes is shorter than its 8-byte head", bytes.len()),
            ));
        }
        let meta_len = u32::from_le_bytes(bytes[0..4].try_into().expect("4 bytes")) as usize;
        let array_count = u32::from_le_bytes(bytes[4..8].try_into().expect("4 bytes")) as usize;
        let head = array_count
            .checked_mul(ARRAY_ENTRY)
            .and_then(|t| t.checked_add(8))
            .filter(|&h| h <= bytes.len())
            .ok_or_else(|| {
                FormatError::invalid_at(4, format!("array table of {array_count} entries does not fit in the section"))
            })?;
        let meta_end = head.checked_add(meta_len).filter(|&e| e <= bytes.len()).ok_or_else(|| {
            FormatError::invalid_at(0, format!("metadata of {meta_len} bytes does not fit in the section"))
        })?;
        let mut arrays = Vec::with_capacity(array_count);
        for i in 0..array_count {
            let e = 8 + i * ARRAY_ENTRY;
            let code = u32::from_le_bytes(bytes[e..e + 4].try_into().expect("4 bytes"));
            let ty = ElemType::from_code(code).ok_or_else(|| {
                FormatError::invalid_at(e as u64, format!("array {i} has unknown element type {code}"))
            })?;
            let off = u64::from_le_bytes(bytes[e + 8..e + 16].try_into().expect("8 bytes"));
            let count = u64::from_le_bytes(bytes[e + 16..e + 24].try_into().expect("8 bytes"));
            let end = count.checked_mul(ty.size() as u64).and_then(|n| n.checked_add(off));
            match end {
                Some(end) if off % 16 == 0 && off >= meta_end as u64 && end <= bytes.len() as u64 => {}
                _ => {
                    return Err(FormatError::invalid_at(
                        e as u64 + 8,
                        format!("array {i} ({count} × {ty:?} at byte {off}) is misaligned or outside the section"),
                    ));
                }
            }
            arrays.push(ArrayRef { ty, start: off as usize, count: count as usize });
        }
        Ok(Record { bytes, meta: &bytes[head..meta_end], arrays })
    }

    /// Decodes the metadata block.
    pub fn meta<T: DeserializeOwned>(&self) -> Result<T> {
        let (value, used) = bincode::serde::decode_from_slice::<T, _>(self.meta, bincode_config())
            .map_err(|e| FormatError::invalid(format!("metadata does not decode: {e}")))?;
        if used != self.meta.len() {
            return Err(FormatError::invalid(format!("metadata is {} bytes but decodes from {used}", self.meta.len())));
        }
        Ok(value)
    }

    /// Number of arrays in the record.
    pub fn array_count(&self) -> usize {
        self.arrays.len()
    }

    /// Array `index` as a slice of `T`: borrowed when the payload is aligned, copied otherwise.
    pub fn array<T: Element>(&self, index: usize) -> Result<Cow<'a, [T]>> {
        self.typed(index, T::TYPE)
    }

    /// Array `index`, which must hold IEEE binary16 values, as bit patterns.
    pub fn array_f16_bits(&self, index: usize) -> Result<Cow<'a, [u16]>> {
        self.typed(index, ElemType::F16)
    }

    /// Array `index` of `T`, checked to hold exactly `count` elements.
    pub fn array_exact<T: Element>(&self, index: usize, count: usize, what: &str) -> Result<Cow<'a, [T]>> {
        let a = self.array::<T>(index)?;
        if a.len() != count {
            return Err(FormatError::invalid(format!("{what}: {} elements, expected {count}", a.len())));
        }
        Ok(a)
    }

    fn typed<T: bytemuck::Pod>(&self, index: usize, ty: ElemType) -> Result<Cow<'a, [T]>> {
        let a = self.arrays.get(index).ok_or_else(|| {
            FormatError::invalid(format!("record has {} arrays, array {index} is missing", self.arrays.len()))
        })?;
        if a.ty != ty {
            return Err(FormatError::invalid(format!("array {index} holds {:?}, expected {ty:?}", a.ty)));
        }
        let raw = &self.bytes[a.start..a.start + a.count * ty.size()];
        Ok(match bytemuck::try_cast_slice::<u8, T>(raw) {
            Ok(s) => Cow::Borrowed(s),
            Err(_) => Cow::Owned(bytemuck::pod_collect_to_vec(raw)),
        })
    }
}
