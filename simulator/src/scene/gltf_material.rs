//! glTF materials and textures to [`Material`] and [`Texture`] (part of the glTF loader; the
//! user manual is the module doc of [`super::gltf_load`]).
//!
//! Colour textures (base colour, emission) decode from sRGB, data textures (metallic-roughness)
//! stay linear. An image used both ways decodes twice; decodes are cached by (image, sRGB), and
//! glTF textures sharing an image but not a sampler get separate copies with their wrap modes.

use std::path::Path;

use glam::Vec3;
use gltf::texture::WrappingMode;

use super::gltf_load::{label, read_uri};
use super::{Material, Texture, TextureRef, WrapMode};
use crate::error::SceneError;

/// Convert every material of `doc`, in order (so scene material `i` is glTF material `i`),
/// decoding the textures they use into `textures`.
pub(super) fn load_materials(
    path: &Path,
    base: &Path,
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    textures: &mut Vec<Texture>,
) -> Result<Vec<Material>, SceneError> {
    let mut loader = TextureLoader { path, base, buffers, textures, cache: Vec::new() };
    doc.materials().map(|m| material(&mut loader, &m)).collect()
}

/// One glTF material.
fn material(tex: &mut TextureLoader, m: &gltf::Material) -> Result<Material, SceneError> {
    let el = label("material", m.index().unwrap_or(0), m.name());
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _alpha] = pbr.base_color_factor();
    let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
    for (name, v) in [("metallicFactor", metallic), ("roughnessFactor", roughness)] {
        if !(0.0..=1.0).contains(&v) {
            return Err(SceneError::invalid(tex.path, format!("{el} {name}"), format!("{v} must lie in [0, 1]")));
        }
    }
    let strength = m.emissive_strength().unwrap_or(1.0);
    let emission = Vec3::from(m.emissive_factor()) * strength;
    let base_color = Vec3::new(r, g, b);
    if !(base_color.is_finite() && base_color.min_element() >= 0.0 && emission.is_finite() && emission.min_element() >= 0.0) {
        return Err(SceneError::invalid(
            tex.path,
            el,
            "baseColorFactor, emissiveFactor and emissive_strength must be finite and non-negative",
        ));
    }
    Ok(Material {
        name: m.name().map(str::to_string).unwrap_or_else(|| el.clone()),
        base_color,
        base_color_texture: tex.get(pbr.base_color_texture(), true, &el, "baseColorTexture")?,
        metallic,
        specular: 1.0,
        roughness,
        metallic_roughness_texture: tex.get(pbr.metallic_roughness_texture(), false, &el, "metallicRoughnessTexture")?,
        emission,
        emission_texture: tex.get(m.emissive_texture(), true, &el, "emissiveTexture")?,
        double_sided: m.double_sided(),
    })
}

/// glTF sampler wrap mode to ours.
fn wrap_mode(w: WrappingMode) -> WrapMode {
    match w {
        WrappingMode::ClampToEdge => WrapMode::ClampToEdge,
        WrappingMode::MirroredRepeat => WrapMode::MirroredRepeat,
        WrappingMode::Repeat => WrapMode::Repeat,
    }
}

/// Decodes images into the scene's textures, at most once per (image, sRGB, wrap modes).
struct TextureLoader<'a> {
    path: &'a Path,
    base: &'a Path,
    buffers: &'a [Vec<u8>],
    textures: &'a mut Vec<Texture>,
    /// (image index, srgb, wrap u, wrap v) -> index in `textures`.
    cache: Vec<((usize, bool, WrapMode, WrapMode), u32)>,
}

impl TextureLoader<'_> {
    /// The texture a material slot refers to, decoding its image on first use.
    fn get(
        &mut self,
        info: Option<gltf::texture::Info>,
        srgb: bool,
        material_el: &str,
        slot: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        let el = format!("{material_el} {slot}");
        if info.tex_coord() != 0 {
            return Err(SceneError::unsupported(
                self.path,
                el,
                format!("texCoord {} : only TEXCOORD_0 is read; re-export with a single UV set", info.tex_coord()),
            ));
        }
        let texture = info.texture();
        let sampler = texture.sampler();
        let image = texture.source();
        let key = (image.index(), srgb, wrap_mode(sampler.wrap_s()), wrap_mode(sampler.wrap_t()));
        if let Some(&(_, i)) = self.cache.iter().find(|(k, _)| *k == key) {
            return Ok(Some(TextureRef { index: i }));
        }
        // same image and colour space under another sampler: copy the texels, not the decode
        let decoded = self.cache.iter().find(|(k, _)| (k.0, k.1) == (key.0, key.1));
        let mut t = match decoded {
            Some(&(_, i)) => self.textures[i as usize].clone(),
            None => {
                let el = format!("{el} (texture {}, {})", texture.index(), label("image", image.index(), image.name()));
                self.decode(&image, srgb, &el)?
            }
        };
        (t.wrap_u, t.wrap_v) = (key.2, key.3);
        let index = self.textures.len() as u32;
        self.textures.push(t);
        self.cache.push((key, index));
        Ok(Some(TextureRef { index }))
    }

    /// Read and decode one image from its bufferView, data URI or file.
    fn decode(&self, image: &gltf::Image, srgb: bool, el: &str) -> Result<Texture, SceneError> {
        let path = self.path;
        let mut texture = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let start = view.offset();
                let bytes = start
                    .checked_add(view.length())
                    .and_then(|end| self.buffers.get(view.buffer().index())?.get(start..end))
                    .ok_or_else(|| {
                        SceneError::invalid(path, el, format!("bufferView {} lies outside its buffer", view.index()))
                    })?;
                Texture::decode(bytes, path, srgb, el)?
            }
            gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                Texture::decode(&read_uri(path, self.base, uri, el)?, path, srgb, el)?
            }
            gltf::image::Source::Uri { uri, .. } => {
                let bytes = read_uri(path, self.base, uri, el)?;
                Texture::decode(&bytes, &self.base.join(uri), srgb, el)?
            }
        };
        texture.name = match (image.name(), image.source()) {
            (Some(n), _) => n.to_string(),
            (None, gltf::image::Source::Uri { uri, .. }) if !uri.starts_with("data:") => uri.to_string(),
            _ => format!("image {}", image.index()),
        };
        Ok(texture)
    }
}
