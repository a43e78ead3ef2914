//! The fin atlas (fur thesis §3.1, fig. 3.6–3.7): one texture, `resolution` wide and `fin_height`
//! tall, composed from K vertical slices of the hair volume, root row at the bottom.

use serde::{Deserialize, Serialize};

use super::{Section, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// The fin texture.
#[derive(Clone, Debug, PartialEq)]
pub struct FinAtlas {
    /// Width in texels (along the edge; one texture repeat).
    pub width: u32,
    /// Height in texels (from the skin, bottom row, to the fur tip, top row).
    pub height: u32,
    /// Number of vertical slices composed (K).
    pub slices: u32,
    /// Alpha, `height × width` bytes, rows top (tip) to bottom (root).
    pub alpha: Vec<u8>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    width: u32,
    height: u32,
    slices: u32,
}

impl FinAtlas {
    /// Fraction of texels with non-zero alpha.
    pub fn coverage(&self) -> f32 {
        if self.alpha.is_empty() {
            return 0.0;
        }
        self.alpha.iter().filter(|&&a| a > 0).count() as f32 / self.alpha.len() as f32
    }
}

impl Section for FinAtlas {
    const KIND: SectionKind = SectionKind::FIN_ATLAS;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        RecordWriter::new(&Meta { width: self.width, height: self.height, slices: self.slices })
            .array::<u8>(&self.alpha)
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let max = super::shell_atlas::MAX_RESOLUTION;
        if m.width == 0 || m.height == 0 || m.width > max || m.height > max || m.slices == 0 {
            return Err(FormatError::invalid(format!(
                "fin atlas {}×{} with {} slices is out of range",
                m.width, m.height, m.slices
            )));
        }
        let alpha =
            r.array_exact::<u8>(0, checked_count(m.width as usize, m.height as usize, "fin alpha")?, "fin alpha")?;
        Ok(FinAtlas { width: m.width, height: m.height, slices: m.slices, alpha: alpha.into_owned() })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "width": self.width,
            "height": self.height,
            "slices": self.slices,
            "coverage": self.coverage(),
        })
    }
}
