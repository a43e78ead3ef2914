//! The skeleton (glTF 2.0 specification, "Skins" and "Transformations"): the joint hierarchy
//! that drives the skin — every node a skin's joints or a rigidly bound mesh depend on, ancestors
//! included, in topological order (a parent before its children) with its rest local TRS — and
//! the *binds*: the skinning palette, one entry per (joint, inverse bind matrix) a vertex
//! influence can name. The skinning matrix of bind `b` is `world(joint[b]) × inverse_bind[b]`.
//!
//! Layout (record, see `docs/format.md` "10 `skeleton`"): metadata `joint_count: u32,
//! bind_count: u32, skin_root: Option<u32>, names: Vec<String>`; arrays 0 parents `u32 × J`
//! (`u32::MAX` for a root), 1 translations `f32 × 3J`, 2 rotations `f32 × 4J` (unit `xyzw`),
//! 3 scales `f32 × 3J`, 4 bind joints `u32 × B`, 5 inverse binds `f32 × 16B` (column-major).

use serde::{Deserialize, Serialize};

use super::{Section, check_coordinates, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Most joints (hierarchy nodes) and most binds a skeleton may hold: bind indices are stored as
/// `u16` by the skin weights.
pub const MAX_JOINTS: usize = 65_535;
/// Longest joint name kept, in bytes (longer names are cut at a character boundary on import).
pub const MAX_NAME_BYTES: usize = 128;
/// Smallest `|det|` of an inverse bind matrix's 3×3 part a reader accepts (a non-invertible
/// inverse bind is refused on import; this is its stored form, with room for tiny scales).
pub const MIN_INVERSE_BIND_DETERMINANT: f64 = 1e-24;
/// Largest deviation of an inverse bind matrix's bottom row from `0, 0, 0, 1` a reader accepts.
/// An inverse bind is an affine transform (the Khronos glTF-Validator refuses any other bottom row
/// of a glTF skin's `inverseBindMatrices` as `ACCESSOR_INVALID_IBM`), and the importer stores it
/// so; the tolerance only admits rounding, and [`Skeleton::affine_inverse_bind`] gives the exact
/// row back.
pub const AFFINE_TOLERANCE: f32 = 1e-6;

/// The joint hierarchy and the skinning palette, struct of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Skeleton {
    /// Joint names (the glTF node names; empty when unnamed).
    pub names: Vec<String>,
    /// Parent joint of each joint, always a smaller index; [`Skeleton::NO_PARENT`] for a root.
    pub parents: Vec<u32>,
    /// Rest local translation (metres, in the parent's frame).
    pub translations: Vec<[f32; 3]>,
    /// Rest local rotation, unit quaternion `xyzw`.
    pub rotations: Vec<[f32; 4]>,
    /// Rest local scale.
    pub scales: Vec<[f32; 3]>,
    /// The joint each bind (palette entry) follows.
    pub bind_joints: Vec<u32>,
    /// Each bind's inverse bind matrix, column-major: mesh (bind) space to the joint's space.
    pub inverse_binds: Vec<[f32; 16]>,
    /// The glTF skin's `skeleton` node (the common root of its joints), when the file names one
    /// and it is part of the hierarchy.
    pub skin_root: Option<u32>,
    /// The glTF node index of each joint (`joint_count` entries), so that an engine that imported
    /// the same file maps its skeleton onto this one without names; empty in a pack written
    /// before they were recorded (layout 1).
    pub nodes: Vec<u32>,
}

impl Skeleton {
    /// The parent index of a root joint.
    pub const NO_PARENT: u32 = u32::MAX;

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.parents.len()
    }

    /// Number of binds (palette entries skin weights index).
    pub fn bind_count(&self) -> usize {
        self.bind_joints.len()
    }

    /// Inverse bind `b` with its bottom row exactly `0, 0, 0, 1` (the decoder accepted it within
    /// [`AFFINE_TOLERANCE`]), as glTF requires of an inverse bind matrix.
    pub fn affine_inverse_bind(&self, b: usize) -> [f32; 16] {
        let mut m = self.inverse_binds[b];
        (m[3], m[7], m[11], m[15]) = (0.0, 0.0, 0.0, 1.0);
        m
    }
}

/// True when the bottom row of the column-major `m` is `0, 0, 0, 1` within [`AFFINE_TOLERANCE`]
/// (false for a non-finite row).
pub fn is_affine(m: &[f32; 16]) -> bool {
    [m[3], m[7], m[11], m[15] - 1.0].iter().all(|x| x.abs() <= AFFINE_TOLERANCE)
}

#[derive(Serialize, Deserialize)]
struct Meta {
    joint_count: u32,
    bind_count: u32,
    skin_root: Option<u32>,
    names: Vec<String>,
}

/// Determinant of the 3×3 part of a column-major 4×4 matrix, in `f64`.
pub(crate) fn det3(m: &[f32; 16]) -> f64 {
    let c = |col: usize, row: usize| f64::from(m[col * 4 + row]);
    c(0, 0) * (c(1, 1) * c(2, 2) - c(2, 1) * c(1, 2)) - c(1, 0) * (c(0, 1) * c(2, 2) - c(2, 1) * c(0, 2))
        + c(2, 0) * (c(0, 1) * c(1, 2) - c(1, 1) * c(0, 2))
}

/// Fails unless every `xyzw` quaternion of `values` has unit length within 1 %.
pub(crate) fn check_unit_quaternions(values: &[f32], what: &str) -> Result<()> {
    check_range(values, -1.0 - 1e-2, 1.0 + 1e-2, what)?;
    match values.chunks_exact(4).position(|q| ((q.iter().map(|x| x * x).sum::<f32>()) - 1.0).abs() > 2e-2) {
        None => Ok(()),
        Some(i) => Err(FormatError::invalid(format!("{what}[{i}] is not a unit quaternion"))),
    }
}

impl Section for Skeleton {
    const KIND: SectionKind = SectionKind::SKELETON;
    const VERSION: u16 = 2;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            joint_count: self.parents.len() as u32,
            bind_count: self.bind_joints.len() as u32,
            skin_root: self.skin_root,
            names: self.names.clone(),
        };
        RecordWriter::new(&meta)
            .array::<u32>(&self.parents)
            .array::<f32>(self.translations.as_flattened())
            .array::<f32>(self.rotations.as_flattened())
            .array::<f32>(self.scales.as_flattened())
            .array::<u32>(&self.bind_joints)
            .array::<f32>(self.inverse_binds.as_flattened())
            .array::<u32>(&self.nodes)
            .finish()
    }

    /// Reads layout 2, or layout 1 (the same without array 6, the joints' glTF nodes).
    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let (j, b) = (m.joint_count as usize, m.bind_count as usize);
        if j > MAX_JOINTS || b > MAX_JOINTS {
            return Err(FormatError::invalid(format!("{j} joints / {b} binds (at most {MAX_JOINTS} each)")));
        }
        if m.names.len() != j {
            return Err(FormatError::invalid(format!("{} joint names for {j} joints", m.names.len())));
        }
        if let Some(i) = m.names.iter().position(|n| n.len() > MAX_NAME_BYTES) {
            return Err(FormatError::invalid(format!("joint name {i} is longer than {MAX_NAME_BYTES} bytes")));
        }
        let parents = r.array_exact::<u32>(0, j, "parents")?;
        let t = r.array_exact::<f32>(1, checked_count(j, 3, "translations")?, "translations")?;
        let q = r.array_exact::<f32>(2, checked_count(j, 4, "rotations")?, "rotations")?;
        let s = r.array_exact::<f32>(3, checked_count(j, 3, "scales")?, "scales")?;
        let bind_joints = r.array_exact::<u32>(4, b, "bind joints")?;
        let ibm = r.array_exact::<f32>(5, checked_count(b, 16, "inverse binds")?, "inverse binds")?;
        // Topological order: a parent comes before its child, so one pass computes world matrices.
        if let Some(i) = parents.iter().enumerate().position(|(i, &p)| p != Skeleton::NO_PARENT && p as usize >= i) {
            return Err(FormatError::invalid(format!(
                "parents[{i}] = {} is not an earlier joint (joints must be in topological order)",
                parents[i]
            )));
        }
        check_coordinates(&t, "translations")?;
        check_unit_quaternions(&q, "rotations")?;
        check_coordinates(&s, "scales")?;
        super::check_indices(&bind_joints, j, "bind joints")?;
        check_coordinates(&ibm, "inverse binds")?;
        let inverse_binds: Vec<[f32; 16]> =
            ibm.chunks_exact(16).map(|c| std::array::from_fn(|k| c[k])).collect::<Vec<_>>();
        if let Some(i) = inverse_binds.iter().position(|m| det3(m).abs() < MIN_INVERSE_BIND_DETERMINANT) {
            return Err(FormatError::invalid(format!("inverse binds[{i}] is not invertible")));
        }
        if let Some(i) = inverse_binds.iter().position(|m| !is_affine(m)) {
            let m = &inverse_binds[i];
            return Err(FormatError::invalid(format!(
                "inverse binds[{i}] is not affine: its bottom row is {:?}, not [0, 0, 0, 1]",
                [m[3], m[7], m[11], m[15]]
            )));
        }
        if let Some(root) = m.skin_root.filter(|&r| r as usize >= j) {
            return Err(FormatError::invalid(format!("skin_root = {root} is out of range (must be below {j})")));
        }
        let nodes = if r.array_count() > 6 { r.array::<u32>(6)?.into_owned() } else { Vec::new() };
        if !(nodes.is_empty() || nodes.len() == j) {
            return Err(FormatError::invalid(format!("{} joint nodes for {j} joints", nodes.len())));
        }
        let mut sorted = nodes.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(FormatError::invalid(format!("glTF node {} is two joints", w[0])));
        }
        Ok(Skeleton {
            names: m.names,
            parents: parents.into_owned(),
            translations: t.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            rotations: q.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
            scales: s.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            bind_joints: bind_joints.into_owned(),
            inverse_binds,
            skin_root: m.skin_root,
            nodes,
        })
    }

    fn summary(&self) -> serde_json::Value {
        let roots = self.parents.iter().filter(|&&p| p == Skeleton::NO_PARENT).count();
        serde_json::json!({
            "joints": self.joint_count(),
            "binds": self.bind_count(),
            "root_joints": roots,
            "skin_root": self.skin_root,
            "joint_names": self.names,
            "joint_nodes": self.nodes,
        })
    }
}
