//! Base-colour textures sampled into vertex colours. Fur takes its colour from the skin (fur
//! thesis §3.2: "derived from the color of the skin"); a textured model without `COLOR_0` would
//! otherwise come out white. Each vertex gets `baseColorFactor × texture(TEXCOORD_n)` (bilinear,
//! wrapping, sRGB decoded to linear). Images come from a buffer view (GLB), a base64 `data:` URI
//! or a relative file inside the asset roots; PNG and JPEG decode, anything else is a warning and
//! the factor alone. A file URI that is refused (an escape from the asset roots, a FIFO, …) is
//! an error, like a refused buffer URI; a missing or unreadable image file stays a warning (an
//! error with `ImportSettings::strict_inputs`, `furbake bake --strict-inputs`).

use std::collections::HashMap;
use std::path::Path;

use gltf::json;

use crate::ImportError;
use crate::external::{ExternalFiles, ExternalRef, Need};
use crate::limits::MAX_FILE_BYTES;
use crate::source::Asset;

/// A decoded base-colour image in linear RGBA.
pub(crate) struct LinearImage {
    width: usize,
    height: usize,
    texels: Vec<[f32; 4]>,
}

impl LinearImage {
    /// Bilinear sample with wrapping (glTF's default REPEAT sampler).
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 4] {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv[0].rem_euclid(1.0) * w - 0.5;
        let y = uv[1].rem_euclid(1.0) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let wrap = |v: f32, n: usize| (v as i64).rem_euclid(n as i64) as usize;
        let (xa, xb) = (wrap(x0, self.width), wrap(x0 + 1.0, self.width));
        let (ya, yb) = (wrap(y0, self.height), wrap(y0 + 1.0, self.height));
        let t = |x: usize, y: usize| self.texels[y * self.width + x];
        let mut out = [0.0; 4];
        for (k, o) in out.iter_mut().enumerate() {
            let top = t(xa, ya)[k] * (1.0 - fx) + t(xb, ya)[k] * fx;
            let bottom = t(xa, yb)[k] * (1.0 - fx) + t(xb, yb)[k] * fx;
            *o = top * (1.0 - fy) + bottom * fy;
        }
        out
    }
}

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Largest image side decoded (bounds the allocation a lying image header could ask for).
const MAX_IMAGE_SIDE: u32 = 16_384;

/// Decoded images by glTF image index (`None` when an image could not be used).
#[derive(Default)]
pub(crate) struct TextureCache {
    images: HashMap<usize, Option<LinearImage>>,
    /// The external image files read (name relative to the glTF's directory, bytes), in the
    /// order they were first used (the scene walk is deterministic): they shape the output, so
    /// the input hash covers them.
    pub external: Vec<(String, Vec<u8>)>,
}

impl TextureCache {
    /// The decoded image of texture `texture`, decoding it on first use. A refused file URI is
    /// an error; other problems become warnings (the caller then uses the base colour factor
    /// alone).
    pub fn get(
        &mut self,
        asset: &Asset,
        file: &Path,
        external: ExternalFiles<'_>,
        texture: usize,
        warnings: &mut Vec<String>,
    ) -> Result<Option<&LinearImage>, ImportError> {
        let Some(texture) = asset.root.textures.get(texture) else { return Ok(None) };
        let image = texture.source.value();
        if !self.images.contains_key(&image) {
            let decoded = match decode_image(asset, external, image, &mut self.external) {
                Ok(img) => Some(img),
                Err(ImageProblem::Refused { uri, problem }) => {
                    return Err(ImportError::ExternalFile {
                        file: file.to_path_buf(),
                        referrer: ExternalRef::Image(image),
                        uri,
                        problem: Box::new(problem),
                    });
                }
                Err(ImageProblem::Unreadable { uri, problem }) if external.strict => {
                    return Err(ImportError::ExternalFile {
                        file: file.to_path_buf(),
                        referrer: ExternalRef::Image(image),
                        uri,
                        problem: Box::new(problem),
                    });
                }
                Err(ImageProblem::Unreadable { uri, problem }) => {
                    warnings.push(format!(
                        "{}: base colour image {image} not used (uri {uri:?} {problem}); the fur takes the base colour factor",
                        file.display()
                    ));
                    None
                }
                Err(ImageProblem::Unusable(why)) => {
                    warnings.push(format!(
                        "{}: base colour image {image} not used ({why}); the fur takes the base colour factor",
                        file.display()
                    ));
                    None
                }
            };
            self.images.insert(image, decoded);
        }
        Ok(self.images.get(&image).and_then(Option::as_ref))
    }

    /// The image of texture `texture` when [`TextureCache::get`] decoded it (`None` when it was
    /// not asked for or could not be used); never decodes.
    pub fn decoded(&self, asset: &Asset, texture: usize) -> Option<&LinearImage> {
        let image = asset.root.textures.get(texture)?.source.value();
        self.images.get(&image).and_then(Option::as_ref)
    }
}

/// Why an image is not used.
enum ImageProblem {
    /// Its file URI was refused: an error.
    Refused { uri: Box<str>, problem: crate::UriProblem },
    /// Its file could not be read (missing, unreadable): a warning, or an error with
    /// `strict_inputs`.
    Unreadable { uri: Box<str>, problem: crate::UriProblem },
    /// Anything else (cannot decode, no source, …): a warning.
    Unusable(String),
}

impl From<&str> for ImageProblem {
    fn from(why: &str) -> Self {
        ImageProblem::Unusable(why.to_owned())
    }
}

impl From<String> for ImageProblem {
    fn from(why: String) -> Self {
        ImageProblem::Unusable(why)
    }
}

fn image_bytes(
    asset: &Asset,
    files: ExternalFiles<'_>,
    image: &json::Image,
    external: &mut Vec<(String, Vec<u8>)>,
) -> Result<Vec<u8>, ImageProblem> {
    if let Some(view) = image.buffer_view {
        let v = asset.root.buffer_views.get(view.value()).ok_or("its buffer view does not exist")?;
        let buffer = asset.buffers.get(v.buffer.value()).ok_or("its buffer does not exist")?;
        let start = v.byte_offset.map_or(0, |o| o.0);
        let end = start
            .checked_add(v.byte_length.0)
            .filter(|&e| e <= buffer.len() as u64)
            .ok_or("its buffer view runs past its buffer")?;
        return Ok(buffer[start as usize..end as usize].to_vec());
    }
    let uri = image.uri.as_deref().ok_or("it has neither a buffer view nor a uri")?;
    if let Some(rest) = uri.strip_prefix("data:") {
        let comma = rest.find(',').ok_or("data: URI without a ','")?;
        if !rest[..comma].ends_with(";base64") {
            return Err("only base64 data: URIs are supported".into());
        }
        return crate::base64::decode(&rest[comma + 1..]).map_err(|e| format!("data: URI: {e}").into());
    }
    let (bytes, name) = match files.read(uri, Need::Whole { limit: MAX_FILE_BYTES }) {
        Ok(read) => read,
        Err(problem) if problem.is_refusal() => return Err(ImageProblem::Refused { uri: uri.into(), problem }),
        Err(problem) => return Err(ImageProblem::Unreadable { uri: uri.into(), problem }),
    };
    external.push((name, bytes.clone()));
    Ok(bytes)
}

fn decode_image(
    asset: &Asset,
    files: ExternalFiles<'_>,
    index: usize,
    external: &mut Vec<(String, Vec<u8>)>,
) -> Result<LinearImage, ImageProblem> {
    let image = asset.root.images.get(index).ok_or("it does not exist")?;
    let bytes = image_bytes(asset, files, image, external)?;
    let reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read its header: {e}"))?;
    let (w, h) = reader.into_dimensions().map_err(|e| format!("cannot read its size: {e}"))?;
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(format!("it is {w}×{h}, outside 1..={MAX_IMAGE_SIDE} per side").into());
    }
    let rgba = image::load_from_memory(&bytes).map_err(|e| format!("cannot decode it: {e}"))?.to_rgba8();
    let texels = rgba
        .pixels()
        .map(|p| [srgb_to_linear(p.0[0]), srgb_to_linear(p.0[1]), srgb_to_linear(p.0[2]), p.0[3] as f32 / 255.0])
        .collect();
    Ok(LinearImage { width: w as usize, height: h as usize, texels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sampling_wraps_and_interpolates() {
        let img = LinearImage { width: 2, height: 1, texels: vec![[0.0; 4], [1.0; 4]] };
        // Texel centres at u = 0.25 and 0.75.
        assert_eq!(img.sample([0.25, 0.5])[0], 0.0);
        assert_eq!(img.sample([0.75, 0.5])[0], 1.0);
        assert!((img.sample([0.5, 0.5])[0] - 0.5).abs() < 1e-6);
        // u = 1.0 wraps to the left edge: halfway between the last and first texel.
        assert!((img.sample([1.0, 0.5])[0] - 0.5).abs() < 1e-6);
        assert_eq!(img.sample([1.25, 0.5]), img.sample([0.25, 0.5]));
        assert!((srgb_to_linear(255) - 1.0).abs() < 1e-6 && srgb_to_linear(0) == 0.0);
    }
}
