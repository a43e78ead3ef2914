//! One baked mass–spring topology (fur thesis §3.4.1, fig. 3.23–3.28): the masses, springs and
//! sticks that move the shells, and the map from every shell vertex to the (root, tip) masses whose
//! positions give its scale vector (eq. 3.35). Struct of arrays: one entry per mass, per spring,
//! per stick and per shell vertex. Building topologies is `furbake-sim`'s job; this module only
//! stores and validates them.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::{MAX_COORDINATE_M, Section, check_coordinates, check_indices, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Marks a shell vertex that carries no fur (it belongs to bare triangles only): it has no masses.
pub const NO_MASS: u32 = u32::MAX;

/// Which of the eight topologies a section holds: an open set of `u32` codes (an unknown code is
/// kept and printed as `unknown(N)`).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct TopologyKind(pub u32);

impl TopologyKind {
    /// A mass on every shell layer, springs between consecutive layers (fig. 3.23).
    pub const CHAIN: TopologyKind = TopologyKind(1);
    /// `k` masses per chain on a subset of layers (fig. 3.24).
    pub const REDUCED_CHAIN: TopologyKind = TopologyKind(2);
    /// Root and tip mass per welded vertex, joined by a fixed-length stick (fig. 3.26).
    pub const STICKS: TopologyKind = TopologyKind(3);
    /// Root and tip mass per welded vertex, joined by a spring (fig. 3.25): 2V masses, V springs.
    pub const SPRING_STICKS: TopologyKind = TopologyKind(4);
    /// Spring–sticks plus springs along the mesh edges between tips (fig. 3.27): 2V, V+E.
    pub const PRISMS: TopologyKind = TopologyKind(5);
    /// Sticks with separate masses per triangle corner (fig. 3.28): 6F masses, 3F sticks.
    pub const SEPARABLE_STICKS: TopologyKind = TopologyKind(6);
    /// Spring–sticks with separate masses per triangle corner: 6F masses, 3F springs.
    pub const SEPARABLE_SPRING_STICKS: TopologyKind = TopologyKind(7);
    /// Prisms with separate masses per triangle corner: 6F masses, 6F springs.
    pub const SEPARABLE_PRISMS: TopologyKind = TopologyKind(8);

    /// Every kind this version knows, in code order.
    pub const KNOWN: [TopologyKind; 8] = [
        Self::CHAIN,
        Self::REDUCED_CHAIN,
        Self::STICKS,
        Self::SPRING_STICKS,
        Self::PRISMS,
        Self::SEPARABLE_STICKS,
        Self::SEPARABLE_SPRING_STICKS,
        Self::SEPARABLE_PRISMS,
    ];

    /// The stable name used on the command line and in JSON, or `None` for unknown codes.
    pub fn name(self) -> Option<&'static str> {
        Some(match self {
            Self::CHAIN => "chain",
            Self::REDUCED_CHAIN => "reduced-chain",
            Self::STICKS => "sticks",
            Self::SPRING_STICKS => "spring-sticks",
            Self::PRISMS => "prisms",
            Self::SEPARABLE_STICKS => "separable-sticks",
            Self::SEPARABLE_SPRING_STICKS => "separable-spring-sticks",
            Self::SEPARABLE_PRISMS => "separable-prisms",
            _ => return None,
        })
    }

    /// Parses a name produced by [`TopologyKind::name`].
    pub fn from_name(name: &str) -> Option<TopologyKind> {
        Self::KNOWN.into_iter().find(|k| k.name() == Some(name))
    }

    /// True for the kinds with separate masses per triangle corner (fur can part).
    pub fn is_separable(self) -> bool {
        matches!(self, Self::SEPARABLE_STICKS | Self::SEPARABLE_SPRING_STICKS | Self::SEPARABLE_PRISMS)
    }

    /// True for the kinds whose root–tip links are fixed-length sticks instead of springs.
    pub fn uses_sticks(self) -> bool {
        matches!(self, Self::STICKS | Self::SEPARABLE_STICKS)
    }
}

impl fmt::Display for TopologyKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(n) => f.write_str(n),
            None => write!(f, "unknown({})", self.0),
        }
    }
}

impl fmt::Debug for TopologyKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// The parameters a topology was built with (stored in the section's metadata). Defaults suit
/// short fur (2 cm) on a mesh in metres.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct TopologyParams {
    /// Fur length: distance from a root mass to its tip mass along the vertex normal, metres.
    /// Default 0.02.
    pub fur_length_m: f32,
    /// Masses per chain for `chain` (one per shell layer, skin included; thesis: 16) — default 16.
    pub chain_layers: u32,
    /// Masses per chain for `reduced-chain` (thesis fig. 3.24c: 3) — default 3. At least 2.
    pub reduced_chain_masses: u32,
    /// Total free mass of one hair chain (shared equally by its free masses), kg. Default 1e-4.
    pub hair_mass_kg: f32,
    /// Mass stored for anchored root masses (the thesis's "sufficiently large" skin mass), kg.
    /// Anchored masses never move in the simulation; the value is informative. Default 1000.
    pub root_mass_kg: f32,
    /// Stiffness of one whole root-to-tip hair, N/m. Chain segments in series get
    /// `stiffness × segments` each, so the chain as a whole has this stiffness. Default 10.
    pub stiffness_n_per_m: f32,
    /// Damping of root-to-tip springs and sticks (eq. 3.24, relative velocity), N·s/m. Default 0.005.
    pub damping_n_s_per_m: f32,
    /// Stiffness of prism springs between neighbouring tips, N/m. Default 10.
    pub edge_stiffness_n_per_m: f32,
    /// Damping of prism springs between neighbouring tips, N·s/m. Default 0.005.
    pub edge_damping_n_s_per_m: f32,
}

impl Default for TopologyParams {
    fn default() -> Self {
        TopologyParams {
            fur_length_m: 0.02,
            chain_layers: 16,
            reduced_chain_masses: 3,
            hair_mass_kg: 1e-4,
            root_mass_kg: 1000.0,
            stiffness_n_per_m: 10.0,
            damping_n_s_per_m: 0.005,
            edge_stiffness_n_per_m: 10.0,
            edge_damping_n_s_per_m: 0.005,
        }
    }
}

/// Shortest and longest fur a new topology accepts, metres: outside, the pack is unusable (a
/// denormal or overflowing rest length, spring constant or scale vector).
pub const FUR_LENGTH_RANGE_M: (f32, f32) = (1e-6, 1e6);
/// Lightest and heaviest hair chain a new topology accepts, kg.
pub const HAIR_MASS_RANGE_KG: (f32, f32) = (1e-9, 1e3);
/// Range of the (informative) anchored root mass, kg.
pub const ROOT_MASS_RANGE_KG: (f32, f32) = (1e-9, 1e9);
/// Largest spring stiffness a new topology accepts, N/m (0 = no spring force).
pub const MAX_STIFFNESS_N_PER_M: f32 = 1e9;
/// Largest damping a new topology accepts, N·s/m (0 = undamped).
pub const MAX_DAMPING_N_S_PER_M: f32 = 1e6;
/// Range of one stored mass, kg: a hair's mass split over up to [`CHAIN_MASSES_RANGE`]'s masses at
/// the light end, an anchored root at the heavy end.
pub const MASS_RANGE_KG: (f32, f32) = (1e-13, 1e9);
/// Masses per chain a topology accepts (`chain_layers`, `reduced_chain_masses`).
pub const CHAIN_MASSES_RANGE: (u32, u32) = (2, 1024);

impl TopologyParams {
    /// The ranges a *new* topology's parameters must lie in, checked field by field in
    /// declaration order; the first violation is returned with the field name, the value and the
    /// allowed range. Stricter than [`Self::validate`], which readers apply to stored packs (so
    /// that any pack ever written stays readable): here the upper bounds and positive minima keep
    /// the built topology finite and usable.
    ///
    /// Ranges: `fur_length_m` [1e-6, 1e6], `chain_layers` and `reduced_chain_masses` 2..=1024,
    /// `hair_mass_kg` [1e-9, 1e3], `root_mass_kg` [1e-9, 1e9], stiffnesses [0, 1e9] N/m,
    /// dampings [0, 1e6] N·s/m; every float finite.
    pub fn check_ranges(&self) -> std::result::Result<(), crate::OutOfRange> {
        fn real(field: &'static str, v: f32, lo: f32, hi: f32) -> std::result::Result<(), crate::OutOfRange> {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                let bound = |b: f32| if b == 0.0 { "0".to_owned() } else { format!("{b:e}") };
                Err(crate::OutOfRange {
                    field,
                    value: v.to_string(),
                    allowed: format!("[{}, {}]", bound(lo), bound(hi)),
                })
            }
        }
        fn count(field: &'static str, v: u32) -> std::result::Result<(), crate::OutOfRange> {
            let (lo, hi) = CHAIN_MASSES_RANGE;
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(crate::OutOfRange { field, value: v.to_string(), allowed: format!("{lo}..={hi}") })
            }
        }
        let (l_lo, l_hi) = FUR_LENGTH_RANGE_M;
        // Exactly zero is allowed: zero-length springs are a stress case the solvers must survive
        // (docs/design.md "Users and their asks", ask 2); denormal lengths are not.
        if self.fur_length_m != 0.0 {
            real("fur_length_m", self.fur_length_m, l_lo, l_hi)?;
        }
        count("chain_layers", self.chain_layers)?;
        count("reduced_chain_masses", self.reduced_chain_masses)?;
        let (m_lo, m_hi) = HAIR_MASS_RANGE_KG;
        real("hair_mass_kg", self.hair_mass_kg, m_lo, m_hi)?;
        let (r_lo, r_hi) = ROOT_MASS_RANGE_KG;
        real("root_mass_kg", self.root_mass_kg, r_lo, r_hi)?;
        real("stiffness_n_per_m", self.stiffness_n_per_m, 0.0, MAX_STIFFNESS_N_PER_M)?;
        real("damping_n_s_per_m", self.damping_n_s_per_m, 0.0, MAX_DAMPING_N_S_PER_M)?;
        real("edge_stiffness_n_per_m", self.edge_stiffness_n_per_m, 0.0, MAX_STIFFNESS_N_PER_M)?;
        real("edge_damping_n_s_per_m", self.edge_damping_n_s_per_m, 0.0, MAX_DAMPING_N_S_PER_M)
    }

    /// [`Self::check_ranges`] as a format error: what a reader and the topology builder require
    /// of stored or given parameters (one set of ranges for writing and reading).
    pub fn validate(&self) -> Result<()> {
        self.check_ranges().map_err(|e| FormatError::invalid(format!("topology parameter {e}")))
    }
}

/// Statistics of the build (shown by `inspect`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TopologyStats {
    /// Welded vertices of the skin mesh the topology was built on.
    pub source_vertices: u32,
    /// Triangles of the skin mesh the topology was built on.
    pub source_triangles: u32,
    /// Triangles skipped because they carry no fur.
    pub bare_triangles: u32,
    /// Vertices whose normal was zero and had to be replaced (face normal, else +Y).
    pub normal_fallbacks: u32,
}

/// A mass–spring topology: masses, springs, sticks and the shell-vertex map, struct of arrays.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringTopology {
    /// Which topology this is.
    pub kind: TopologyKind,
    /// Build parameters.
    pub params: TopologyParams,
    /// Build statistics.
    pub stats: TopologyStats,
    /// Per mass: rest position in the mesh frame, metres.
    pub mass_rest_positions: Vec<[f32; 3]>,
    /// Per mass: mass, kg (> 0).
    pub mass_kg: Vec<f32>,
    /// Per mass: 1 when anchored to the skin (never moves in the mesh frame), else 0.
    pub mass_anchored: Vec<u8>,
    /// Per spring: the two mass indices (distinct).
    pub spring_ends: Vec<[u32; 2]>,
    /// Per spring: rest length, metres (≥ 0).
    pub spring_rest_lengths_m: Vec<f32>,
    /// Per spring: Hooke constant (eq. 3.23), N/m (≥ 0).
    pub spring_stiffness_n_per_m: Vec<f32>,
    /// Per spring: viscosity constant (eq. 3.24), N·s/m (≥ 0).
    pub spring_damping_n_s_per_m: Vec<f32>,
    /// Per stick: the two mass indices (distinct; the first is the one nearer the skin).
    pub stick_ends: Vec<[u32; 2]>,
    /// Per stick: fixed length, metres (≥ 0).
    pub stick_lengths_m: Vec<f32>,
    /// Per shell vertex — per welded vertex for non-separable kinds, per triangle corner
    /// (`3 × triangle + corner`) for separable ones: the (root, tip) masses of eq. 3.35, or
    /// `[NO_MASS, NO_MASS]` for a vertex without fur.
    pub shell_vertex_masses: Vec<[u32; 2]>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    kind: TopologyKind,
    params: TopologyParams,
    stats: TopologyStats,
    masses: u64,
    springs: u64,
    sticks: u64,
    shell_vertices: u64,
}

impl SpringTopology {
    /// The layout version whose record metadata starts with the kind's `u32` code (bincode,
    /// fixed-width little-endian), so a reader can learn the kind from four bytes
    /// ([`SpringTopology::kind_from_meta_prefix`]) without reading the section.
    pub const PEEKABLE_VERSION: u16 = 1;

    /// The topology kind from the first four bytes of a [`Self::PEEKABLE_VERSION`] record's
    /// metadata (its first field).
    pub fn kind_from_meta_prefix(prefix: [u8; 4]) -> TopologyKind {
        TopologyKind(u32::from_le_bytes(prefix))
    }

    /// Number of anchored masses.
    pub fn anchored_count(&self) -> usize {
        self.mass_anchored.iter().filter(|&&a| a != 0).count()
    }

    /// Number of shell vertices that carry fur.
    pub fn furry_shell_vertices(&self) -> usize {
        self.shell_vertex_masses.iter().filter(|m| m[0] != NO_MASS).count()
    }
}

impl Section for SpringTopology {
    const KIND: SectionKind = SectionKind::SPRING_TOPOLOGY;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            kind: self.kind,
            params: self.params.clone(),
            stats: self.stats.clone(),
            masses: self.mass_kg.len() as u64,
            springs: self.spring_ends.len() as u64,
            sticks: self.stick_ends.len() as u64,
            shell_vertices: self.shell_vertex_masses.len() as u64,
        };
        RecordWriter::new(&meta)
            .array::<f32>(self.mass_rest_positions.as_flattened())
            .array::<f32>(&self.mass_kg)
            .array::<u8>(&self.mass_anchored)
            .array::<u32>(self.spring_ends.as_flattened())
            .array::<f32>(&self.spring_rest_lengths_m)
            .array::<f32>(&self.spring_stiffness_n_per_m)
            .array::<f32>(&self.spring_damping_n_s_per_m)
            .array::<u32>(self.stick_ends.as_flattened())
            .array::<f32>(&self.stick_lengths_m)
            .array::<u32>(self.shell_vertex_masses.as_flattened())
            .finish()
    }

    // Validation happens here once; consumers (the simulator, the runtime) trust the result:
    // every index is in range, every real is finite, masses are positive, lengths and constants
    // are non-negative, and shell vertices have either both masses or neither.
    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        m.params.validate()?;
        let as_count = |v: u64, what: &str| {
            usize::try_from(v).map_err(|_| FormatError::invalid(format!("{what} count {v} does not fit in memory")))
        };
        let nm = as_count(m.masses, "mass")?;
        let ns = as_count(m.springs, "spring")?;
        let nt = as_count(m.sticks, "stick")?;
        let nv = as_count(m.shell_vertices, "shell vertex")?;
        // `array_exact` compares the claimed counts with the array lengths, which the record layer
        // has already bounded by the payload size, so a lying count cannot cause an allocation.
        let pos = r.array_exact::<f32>(0, checked_count(nm, 3, "mass positions")?, "mass rest positions")?;
        let mass = r.array_exact::<f32>(1, nm, "mass_kg")?;
        let anchored = r.array_exact::<u8>(2, nm, "mass_anchored")?;
        let s_ends = r.array_exact::<u32>(3, checked_count(ns, 2, "spring ends")?, "spring ends")?;
        let s_rest = r.array_exact::<f32>(4, ns, "spring rest lengths")?;
        let s_k = r.array_exact::<f32>(5, ns, "spring stiffness")?;
        let s_c = r.array_exact::<f32>(6, ns, "spring damping")?;
        let t_ends = r.array_exact::<u32>(7, checked_count(nt, 2, "stick ends")?, "stick ends")?;
        let t_len = r.array_exact::<f32>(8, nt, "stick lengths")?;
        let shell = r.array_exact::<u32>(9, checked_count(nv, 2, "shell vertex masses")?, "shell vertex masses")?;

        // Every value in the range the parameters' ranges imply, so a pack that reads also
        // simulates (docs/design.md "Runtime: packs").
        check_coordinates(&pos, "mass rest positions")?;
        check_range(&mass, MASS_RANGE_KG.0, MASS_RANGE_KG.1, "mass_kg")?;
        check_range(&s_rest, 0.0, MAX_COORDINATE_M, "spring rest lengths")?;
        check_range(&s_k, 0.0, MAX_STIFFNESS_N_PER_M, "spring stiffness")?;
        check_range(&s_c, 0.0, MAX_DAMPING_N_S_PER_M, "spring damping")?;
        check_range(&t_len, 0.0, MAX_COORDINATE_M, "stick lengths")?;
        if let Some(i) = anchored.iter().position(|&x| x > 1) {
            return Err(FormatError::invalid(format!("mass_anchored[{i}] = {} (must be 0 or 1)", anchored[i])));
        }
        for (name, values) in [
            ("spring rest lengths", &s_rest),
            ("spring stiffness", &s_k),
            ("spring damping", &s_c),
            ("stick lengths", &t_len),
        ] {
            if let Some(i) = values.iter().position(|&x| x < 0.0) {
                return Err(FormatError::invalid(format!("{name}[{i}] = {} is negative", values[i])));
            }
        }
        check_indices(&s_ends, nm, "spring ends")?;
        check_indices(&t_ends, nm, "stick ends")?;
        for (what, ends) in [("spring", &s_ends), ("stick", &t_ends)] {
            if let Some(i) = ends.chunks_exact(2).position(|e| e[0] == e[1]) {
                return Err(FormatError::invalid(format!("{what} {i} joins mass {} to itself", ends[2 * i])));
            }
        }
        // A link is built between two rest positions with their distance as its length, so a
        // stored length that disagrees is corruption — and a far-too-short one makes every step
        // of the implicit solvers split into thousands of substeps (their limit scales with the
        // shortest link).
        check_link_lengths(&pos, &s_ends, &s_rest, "spring")?;
        check_link_lengths(&pos, &t_ends, &t_len, "stick")?;
        for (i, e) in shell.chunks_exact(2).enumerate() {
            let ok =
                (e[0] == NO_MASS && e[1] == NO_MASS) || ((e[0] as usize) < nm && (e[1] as usize) < nm && e[0] != e[1]);
            if !ok {
                return Err(FormatError::invalid(format!(
                    "shell vertex {i} maps to masses ({}, {}) (must be two distinct masses below {nm}, or none)",
                    e[0], e[1]
                )));
            }
        }
        let pairs = |a: &[u32]| a.chunks_exact(2).map(|c| [c[0], c[1]]).collect::<Vec<_>>();
        Ok(SpringTopology {
            kind: m.kind,
            params: m.params,
            stats: m.stats,
            mass_rest_positions: pos.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            mass_kg: mass.into_owned(),
            mass_anchored: anchored.into_owned(),
            spring_ends: pairs(&s_ends),
            spring_rest_lengths_m: s_rest.into_owned(),
            spring_stiffness_n_per_m: s_k.into_owned(),
            spring_damping_n_s_per_m: s_c.into_owned(),
            stick_ends: pairs(&t_ends),
            stick_lengths_m: t_len.into_owned(),
            shell_vertex_masses: pairs(&shell),
        })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "kind": self.kind.to_string(),
            "masses": self.mass_kg.len(),
            "springs": self.spring_ends.len(),
            "sticks": self.stick_ends.len(),
            "anchored_masses": self.anchored_count(),
            "shell_vertices": self.shell_vertex_masses.len(),
            "furry_shell_vertices": self.furry_shell_vertices(),
            "fur_length_m": self.params.fur_length_m,
            "hair_mass_kg": self.params.hair_mass_kg,
            "stiffness_n_per_m": self.params.stiffness_n_per_m,
            "damping_n_s_per_m": self.params.damping_n_s_per_m,
            "edge_stiffness_n_per_m": self.params.edge_stiffness_n_per_m,
            "edge_damping_n_s_per_m": self.params.edge_damping_n_s_per_m,
            "source_vertices": self.stats.source_vertices,
            "source_triangles": self.stats.source_triangles,
            "bare_triangles": self.stats.bare_triangles,
            "normal_fallbacks": self.stats.normal_fallbacks,
        })
    }
}

/// Relative tolerance between a link's stored length and the distance of its ends' rest
/// positions (a bake writes them from the same `f32` positions: measured ≤ 3e-6).
pub const LINK_LENGTH_TOLERANCE: f64 = 1e-3;

/// Fails unless every link's stored length equals the distance between its ends' rest positions
/// within [`LINK_LENGTH_TOLERANCE`] (plus `f32` rounding of the coordinates). `ends` were checked
/// against the mass count, so the lookups are in range.
fn check_link_lengths(pos: &[f32], ends: &[u32], lengths: &[f32], what: &str) -> Result<()> {
    let at = |m: u32| {
        let k = 3 * m as usize;
        [pos[k] as f64, pos[k + 1] as f64, pos[k + 2] as f64]
    };
    for (i, (e, &len)) in ends.chunks_exact(2).zip(lengths).enumerate() {
        let (a, b) = (at(e[0]), at(e[1]));
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        let scale = a.iter().chain(&b).fold(0.0f64, |m, x| m.max(x.abs()));
        let slack = LINK_LENGTH_TOLERANCE * d + 8.0 * f32::EPSILON as f64 * scale;
        if (len as f64 - d).abs() > slack {
            return Err(FormatError::invalid(format!(
                "{what} {i} is {len} m long but its masses {} and {} rest {d} m apart",
                e[0], e[1]
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_ranges_names_the_first_bad_field_with_its_range() {
        assert_eq!(TopologyParams::default().check_ranges(), Ok(()));
        let mut cases = 0;
        for (field, set) in [
            ("stiffness_n_per_m", (|p: &mut TopologyParams| p.stiffness_n_per_m = -1.0) as fn(&mut TopologyParams)),
            ("hair_mass_kg", |p| p.hair_mass_kg = 1e-45),
            ("fur_length_m", |p| p.fur_length_m = 3e38),
            ("damping_n_s_per_m", |p| p.damping_n_s_per_m = f32::NAN),
            ("reduced_chain_masses", |p| p.reduced_chain_masses = 1),
        ] {
            let mut p = TopologyParams::default();
            set(&mut p);
            let err = p.check_ranges().unwrap_err();
            assert_eq!(err.field, field);
            assert!(err.to_string().starts_with(field), "{err}");
            cases += 1;
        }
        assert_eq!(cases, 5);
        let err = TopologyParams { stiffness_n_per_m: -1.0, ..Default::default() }.check_ranges().unwrap_err();
        assert_eq!(err.to_string(), "stiffness_n_per_m = -1 is out of range (allowed: [0, 1e9])");
    }

    fn sample() -> SpringTopology {
        SpringTopology {
            kind: TopologyKind::PRISMS,
            params: TopologyParams::default(),
            stats: TopologyStats { source_vertices: 2, source_triangles: 0, bare_triangles: 0, normal_fallbacks: 0 },
            mass_rest_positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.02, 0.0], [1.0, 0.02, 0.0]],
            mass_kg: vec![1000.0, 1000.0, 5e-5, 5e-5],
            mass_anchored: vec![1, 1, 0, 0],
            spring_ends: vec![[0, 2], [1, 3], [2, 3]],
            spring_rest_lengths_m: vec![0.02, 0.02, 1.0],
            spring_stiffness_n_per_m: vec![10.0, 10.0, 5.0],
            spring_damping_n_s_per_m: vec![0.005, 0.005, 0.001],
            stick_ends: vec![[0, 2]],
            stick_lengths_m: vec![0.02],
            shell_vertex_masses: vec![[0, 2], [1, 3], [NO_MASS, NO_MASS]],
        }
    }

    #[test]
    fn round_trip_and_summary() {
        let t = sample();
        let back = SpringTopology::decode(&t.encode()).expect("a freshly encoded topology decodes");
        assert_eq!(back, t);
        let s = t.summary();
        assert_eq!(s["kind"], "prisms");
        assert_eq!(s["masses"], 4);
        assert_eq!(s["springs"], 3);
        assert_eq!(s["sticks"], 1);
        assert_eq!(s["furry_shell_vertices"], 2);
    }

    #[test]
    fn kind_names_are_exact_and_open() {
        let names: Vec<_> = TopologyKind::KNOWN.iter().map(|k| k.name().expect("known kinds have names")).collect();
        assert_eq!(
            names,
            [
                "chain",
                "reduced-chain",
                "sticks",
                "spring-sticks",
                "prisms",
                "separable-sticks",
                "separable-spring-sticks",
                "separable-prisms"
            ]
        );
        for k in TopologyKind::KNOWN {
            assert_eq!(TopologyKind::from_name(k.name().expect("known")), Some(k));
        }
        assert_eq!(TopologyKind(99).to_string(), "unknown(99)");
        let mut t = sample();
        t.kind = TopologyKind(99);
        assert_eq!(SpringTopology::decode(&t.encode()).expect("unknown kinds still decode").kind, TopologyKind(99));
    }

    /// Every corruption must come back as an `Invalid` error, never a panic.
    #[test]
    fn corrupted_payloads_are_rejected() {
        let mut cases: Vec<(&str, SpringTopology)> = Vec::new();
        let mut t = sample();
        t.spring_ends[1] = [1, 4];
        cases.push(("spring index out of range", t));
        let mut t = sample();
        t.stick_ends[0] = [2, 2];
        cases.push(("self stick", t));
        let mut t = sample();
        t.mass_kg[3] = 0.0;
        cases.push(("zero mass", t));
        let mut t = sample();
        t.mass_kg[2] = f32::NAN;
        cases.push(("NaN mass", t));
        let mut t = sample();
        t.spring_rest_lengths_m[0] = -1.0;
        cases.push(("negative rest length", t));
        let mut t = sample();
        t.mass_anchored[0] = 7;
        cases.push(("anchored flag 7", t));
        let mut t = sample();
        t.spring_rest_lengths_m[2] = 1e-6;
        cases.push(("spring far shorter than its masses' distance", t));
        let mut t = sample();
        t.stick_lengths_m[0] = 0.5;
        cases.push(("stick longer than its masses' distance", t));
        let mut t = sample();
        t.shell_vertex_masses[2] = [NO_MASS, 1];
        cases.push(("half-mapped shell vertex", t));
        let mut t = sample();
        t.mass_rest_positions[0][1] = f32::INFINITY;
        cases.push(("infinite position", t));
        let mut t = sample();
        t.params.chain_layers = 0;
        cases.push(("bad parameter", t));
        let mut checked = 0;
        for (what, t) in &cases {
            let err = SpringTopology::decode(&t.encode()).expect_err(what);
            assert!(err.is_bad_file(), "{what}: {err}");
            checked += 1;
        }
        // Arrays that disagree with the counts in the metadata: drop one spring from one array.
        let mut t = sample();
        t.spring_stiffness_n_per_m.pop();
        assert!(SpringTopology::decode(&t.encode()).is_err());
        checked += 1;
        assert_eq!(checked, cases.len() + 1);
    }

    /// Truncations and byte flips anywhere in the payload never panic.
    #[test]
    fn truncated_and_flipped_payloads_never_panic() {
        let bytes = sample().encode();
        let mut errors = 0;
        for len in 0..bytes.len() {
            if SpringTopology::decode(&bytes[..len]).is_err() {
                errors += 1;
            }
        }
        assert_eq!(errors, bytes.len(), "every strict prefix must be rejected");
        let mut decoded = 0;
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0xA5;
            if SpringTopology::decode(&b).is_ok() {
                decoded += 1;
            }
        }
        assert!(decoded < bytes.len(), "flipping bytes must break most payloads");
    }

    /// A metadata block claiming billions of masses over tiny arrays fails without allocating.
    #[test]
    fn lying_counts_fail_fast() {
        let t = sample();
        let meta = Meta {
            kind: t.kind,
            params: t.params.clone(),
            stats: t.stats.clone(),
            masses: u64::MAX / 2,
            springs: 3,
            sticks: 1,
            shell_vertices: 3,
        };
        let bytes = RecordWriter::new(&meta)
            .array::<f32>(t.mass_rest_positions.as_flattened())
            .array::<f32>(&t.mass_kg)
            .array::<u8>(&t.mass_anchored)
            .finish();
        assert!(SpringTopology::decode(&bytes).expect_err("lying count").is_bad_file());
    }

    #[test]
    fn a_spring_far_shorter_than_its_rest_positions_is_refused() {
        // Cause: a stored rest length was checked only for range, so a pack with one spring of
        // 1e-6 m between masses 11 m apart verified, and the implicit solver's rotation limit
        // (which scales with the shortest link) split the first 0.02 s step into 10,000
        // substeps: 6 s for one step of the Fox (found by furbake-fuzz, packs seed 1 case 6517).
        let mut t = sample();
        t.spring_rest_lengths_m[2] = 1e-6;
        let err = SpringTopology::decode(&t.encode()).unwrap_err();
        assert!(err.to_string().contains("spring 2 is 0.000001 m long"), "{err}");
        // Rounding of the positions is not corruption.
        let mut t = sample();
        t.spring_rest_lengths_m[2] = 1.0 + 2e-6;
        assert!(SpringTopology::decode(&t.encode()).is_ok());
    }

    #[test]
    fn stored_values_outside_the_parameter_ranges_are_rejected() {
        // Cause: a spring of 1e12 N/m or a mass of 1e-30 kg decoded (finite and positive), and
        // every simulation of the pack then failed.
        let mut cases = 0;
        for (what, damage) in [
            (
                "spring stiffness",
                (|t: &mut SpringTopology| t.spring_stiffness_n_per_m[0] = 1e12) as fn(&mut SpringTopology),
            ),
            ("mass_kg", |t| t.mass_kg[1] = 1e-30),
            ("mass rest positions", |t| t.mass_rest_positions[0][1] = 3e38),
            ("topology parameter stiffness_n_per_m", |t| t.params.stiffness_n_per_m = 1e12),
        ] {
            let mut t = sample();
            damage(&mut t);
            let err = SpringTopology::decode(&t.encode()).unwrap_err();
            assert!(err.to_string().contains(what), "{what}: {err}");
            cases += 1;
        }
        assert_eq!(cases, 4);
        let mut zero = sample();
        zero.params.fur_length_m = 0.0;
        assert!(SpringTopology::decode(&zero.encode()).is_ok(), "zero-length fur is a stress case, not an error");
    }
}
