//! glTF materials and textures to [`Material`] and [`Texture`] (part of the glTF loader; the
//! user manual is the module doc of [`super::gltf_load`]).
//!
//! Colour textures (base colour, emission) decode from sRGB, data textures (metallic-roughness)
//! stay linear. An image used both ways decodes twice; decodes are cached by (image, sRGB), and
//! glTF textures sharing an image but not a sampler get separate copies with their wrap modes.
//!
//! `KHR_materials_specular`: only the scalar `specularFactor` is read (our BSDF has one dielectric
//! specular strength); a non-white `specularColorFactor`, a `specularTexture` or a
//! `specularColorTexture` is ignored with a warning.

use std::path::Path;

use glam::Vec3;
use gltf::texture::WrappingMode;

use super::gltf_load::{label, percent_decode, read_uri};
use super::{Material, Texture, TextureRef, WrapMode};
use crate::error::SceneError;

/// Convert every material of `doc`, in order (so scene material `i` is glTF material `i`),
/// decoding the textures they use into `textures` and pushing what is ignored to `warnings`.
pub(super) fn load_materials(
    path: &Path,
    base: &Path,
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    textures: &mut Vec<Texture>,
    warnings: &mut Vec<String>,
) -> Result<Vec<Material>, SceneError> {
    let mut loader = TextureLoader { path, base, buffers, textures, cache: Vec::new() };
    doc.materials().map(|m| material(&mut loader, &m, warnings)).collect()
}

/// One glTF material.
fn material(tex: &mut TextureLoader, m: &gltf::Material, warnings: &mut Vec<String>) -> Result<Material, SceneError> {
    let el = label("material", m.index().unwrap_or(0), m.name());
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _alpha] = pbr.base_color_factor();
    let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
    let specular = m.specular().map_or(1.0, |s| specular_strength(tex.path, &el, &s, warnings));
    for (name, v) in [("metallicFactor", metallic), ("roughnessFactor", roughness), ("specularFactor", specular)] {
        if !(0.0..=1.0).contains(&v) {
            return Err(SceneError::invalid(tex.path, format!("{el} {name}"), format!("{v} must lie in [0, 1]")));
        }
    }
    let strength = m.emissive_strength().unwrap_or(1.0);
    if !(strength.is_finite() && strength >= 0.0) {
        return Err(SceneError::invalid(
            tex.path,
            format!("{el} KHR_materials_emissive_strength.emissiveStrength"),
            format!("{strength} must be finite and non-negative"),
        ));
    }
    let emission = Vec3::from(m.emissive_factor()) * strength;
    let base_color = Vec3::new(r, g, b);
    if !(base_color.is_finite()
        && base_color.min_element() >= 0.0
        && emission.is_finite()
        && emission.min_element() >= 0.0)
    {
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
        specular,
        roughness,
        metallic_roughness_texture: tex.get(
            pbr.metallic_roughness_texture(),
            false,
            &el,
            "metallicRoughnessTexture",
        )?,
        emission,
        emission_texture: tex.get(m.emissive_texture(), true, &el, "emissiveTexture")?,
        double_sided: m.double_sided(),
    })
}

/// The `KHR_materials_specular` strength `specularFactor`; warns about the parts we ignore (the
/// F0 colour and both textures), since our model has only the scalar strength.
fn specular_strength(path: &Path, el: &str, s: &gltf::material::Specular, warnings: &mut Vec<String>) -> f32 {
    let mut ignored = Vec::new();
    if s.specular_color_factor() != [1.0; 3] {
        ignored.push(format!("specularColorFactor {:?}", s.specular_color_factor()));
    }
    if s.specular_texture().is_some() {
        ignored.push("specularTexture".to_string());
    }
    if s.specular_color_texture().is_some() {
        ignored.push("specularColorTexture".to_string());
    }
    if !ignored.is_empty() {
        warnings.push(format!(
            "{}: {el}: KHR_materials_specular {} ignored (only the scalar specularFactor is read)",
            path.display(),
            ignored.join(", "),
        ));
    }
    s.specular_factor()
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
                Texture::decode(&bytes, &self.base.join(percent_decode(uri)), srgb, el)?
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

#[cfg(test)]
mod tests {
    use super::super::gltf_fixture::{assert_close, base64, png, temp_dir, Doc};
    use super::super::gltf_load::load;
    use super::*;
    use crate::base::colour::srgb_to_linear;
    use glam::{Vec2, Vec4};

    /// 2x2 RGBA8: a purple, a dark green, a half-transparent white, a dark blue-grey.
    const TEXELS: [u8; 16] = [128, 0, 255, 255, 0, 64, 0, 255, 255, 255, 255, 128, 10, 20, 30, 255];

    /// A textured triangle (with UVs) using material 0 under one node.
    fn textured_doc() -> Doc {
        let mut d = Doc::default();
        let p = d.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
        let uv = d.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
        d.meshes
            .push(format!(r#"{{"primitives":[{{"attributes":{{"POSITION":{p},"TEXCOORD_0":{uv}}},"material":0}}]}}"#));
        d.node(r#"{"mesh":0}"#);
        d
    }

    #[test]
    fn glb_png_texture_decodes_srgb_and_maps_wrap_modes() {
        let mut d = textured_doc();
        let view = d.view(&png(2, 2, &TEXELS));
        d.extra.push(format!(
            r#""materials":[{{"name":"Painted","doubleSided":true,"pbrMetallicRoughness":{{
                "baseColorFactor":[0.5,0.25,1,1],"baseColorTexture":{{"index":0}},
                "metallicFactor":0.3,"roughnessFactor":0.6,"metallicRoughnessTexture":{{"index":0}}}}}}],
            "textures":[{{"source":0,"sampler":0}}],
            "samplers":[{{"wrapS":33071,"wrapT":33648}}],
            "images":[{{"bufferView":{view},"mimeType":"image/png"}}]"#
        ));
        let s = load(&d.write_glb(&temp_dir("glb"), "painted")).unwrap();
        assert_eq!(s.mesh.uvs, vec![Vec2::ZERO, Vec2::X, Vec2::Y]);
        let m = &s.materials[0];
        assert_eq!(m.name, "Painted");
        assert_close(m.base_color, Vec3::new(0.5, 0.25, 1.0));
        assert_eq!((m.metallic, m.roughness, m.specular, m.double_sided), (0.3, 0.6, 1.0, true));
        assert_eq!(m.base_color_texture, Some(TextureRef { index: 0 }));
        assert_eq!(m.metallic_roughness_texture, Some(TextureRef { index: 1 }));
        // one image used as colour (sRGB-decoded) and as data (linear): two textures
        assert_eq!(s.textures.len(), 2);
        let (colour, data) = (&s.textures[0], &s.textures[1]);
        let c = 128.0 / 255.0;
        let expected = Vec4::new(srgb_to_linear(c), 0.0, 1.0, 1.0);
        assert!((colour.texels[0] - expected).abs().max_element() < 1e-6, "{}", colour.texels[0]);
        assert!((srgb_to_linear(c) - 0.2158605).abs() < 1e-6);
        assert!((data.texels[0] - Vec4::new(c, 0.0, 1.0, 1.0)).abs().max_element() < 1e-6);
        // alpha stays linear; the second row is the image's second row
        assert!((colour.texels[2].w - c).abs() < 1e-6);
        assert!((colour.texels[1].y - srgb_to_linear(64.0 / 255.0)).abs() < 1e-6);
        for t in [colour, data] {
            assert_eq!((t.width, t.height), (2, 2));
            assert_eq!((t.wrap_u, t.wrap_v), (WrapMode::ClampToEdge, WrapMode::MirroredRepeat));
        }
    }

    #[test]
    fn emissive_strength_multiplies_and_textures_are_shared() {
        let mut d = textured_doc();
        let uri = format!("data:image/png;base64,{}", base64(&png(2, 2, &TEXELS)));
        d.extra.push(format!(
            r#""extensionsUsed":["KHR_materials_emissive_strength"],
            "materials":[
              {{"emissiveFactor":[1,0.5,0],"emissiveTexture":{{"index":0}},
                "extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":4}}}}}},
              {{"name":"Plain","emissiveFactor":[0.25,0.25,0.25],"emissiveTexture":{{"index":0}},
                "pbrMetallicRoughness":{{"baseColorTexture":{{"index":1}}}}}}],
            "textures":[{{"source":0}},{{"source":0,"sampler":0}}],
            "samplers":[{{"wrapS":10497,"wrapT":33071}}],
            "images":[{{"uri":"{uri}"}}]"#
        ));
        let s = load(&d.write_external(&temp_dir("emit"), "emit")).unwrap();
        let (a, b) = (&s.materials[0], &s.materials[1]);
        assert_close(a.emission, Vec3::new(4.0, 2.0, 0.0));
        assert_close(b.emission, Vec3::splat(0.25));
        assert_eq!(a.name, "material 0");
        assert!(!a.double_sided);
        // glTF defaults
        assert_eq!((a.metallic, a.roughness), (1.0, 1.0));
        // texture 0 (default sampler) decoded once for both materials; texture 1 shares the
        // image and colour space but not the sampler: same texels, its own wrap modes
        assert_eq!(a.emission_texture, Some(TextureRef { index: 0 }));
        assert_eq!(b.emission_texture, Some(TextureRef { index: 0 }));
        assert_eq!(b.base_color_texture, Some(TextureRef { index: 1 }));
        assert_eq!(s.textures.len(), 2);
        assert_eq!(s.textures[0].texels, s.textures[1].texels);
        assert_eq!((s.textures[0].wrap_u, s.textures[0].wrap_v), (WrapMode::Repeat, WrapMode::Repeat));
        assert_eq!((s.textures[1].wrap_u, s.textures[1].wrap_v), (WrapMode::Repeat, WrapMode::ClampToEdge));
        assert!((s.textures[0].texels[3].z - srgb_to_linear(30.0 / 255.0)).abs() < 1e-6);
    }

    #[test]
    fn specular_factor_is_read_and_colour_is_ignored_with_a_warning() {
        let mut d = textured_doc();
        d.extra.push(
            r#""extensionsUsed":["KHR_materials_specular"],
            "materials":[
              {"name":"Satin","extensions":{"KHR_materials_specular":{"specularFactor":0.25}}},
              {"name":"Tinted","extensions":{"KHR_materials_specular":{"specularColorFactor":[1,0.5,0.5]}}},
              {"name":"Plain"}]"#
                .into(),
        );
        let s = load(&d.write_embedded(&temp_dir("spec"), "spec")).unwrap();
        let specular: Vec<f32> = s.materials.iter().map(|m| m.specular).collect();
        // factor read; default 1 inside the extension and without it
        assert_eq!(specular, vec![0.25, 1.0, 1.0]);
        // only the non-white colour factor warns, naming the material and what is ignored
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        let w = &s.warnings[0];
        assert!(w.contains("material 1 \"Tinted\"") && w.contains("specularColorFactor [1.0, 0.5, 0.5]"), "{w}");
        assert!(w.contains("ignored"), "{w}");
    }

    #[test]
    fn specular_factor_outside_unit_interval_is_invalid() {
        let mut d = textured_doc();
        d.extra.push(
            r#""materials":[{"name":"Hot","extensions":{"KHR_materials_specular":{"specularFactor":1.5}}}]"#.into(),
        );
        let e = load(&d.write_embedded(&temp_dir("spec"), "spec_bad")).unwrap_err();
        assert!(matches!(e, SceneError::Invalid { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("material 0 \"Hot\" specularFactor") && msg.contains("[0, 1]"), "{msg}");
    }

    #[test]
    fn missing_or_undecodable_texture_is_invalid() {
        let dir = temp_dir("notex");
        let mut d = textured_doc();
        d.extra.push(
            r#""materials":[{"name":"Wood","pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
            "textures":[{"source":0}],"images":[{"uri":"nope.png"}]"#
                .into(),
        );
        let e = load(&d.write_embedded(&dir, "missing")).unwrap_err();
        assert!(matches!(e, SceneError::Invalid { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("material 0 \"Wood\" baseColorTexture") && msg.contains("nope.png"), "{msg}");

        fixture_write(&dir, "nope.png", b"not a png");
        let e = load(&d.write_embedded(&dir, "garbage")).unwrap_err();
        assert!(matches!(e, SceneError::Invalid { .. }) && e.to_string().contains("cannot be decoded"), "{e}");
    }

    #[test]
    fn tex_coord_1_is_unsupported() {
        let mut d = textured_doc();
        let uri = format!("data:image/png;base64,{}", base64(&png(2, 2, &TEXELS)));
        d.extra.push(format!(
            r#""materials":[{{"name":"Wood","pbrMetallicRoughness":{{"baseColorTexture":{{"index":0,"texCoord":1}}}}}}],
            "textures":[{{"source":0}}],"images":[{{"uri":"{uri}"}}]"#
        ));
        let e = load(&d.write_embedded(&temp_dir("uv1"), "uv1")).unwrap_err();
        assert!(
            matches!(e, SceneError::Unsupported { ref element, .. }
                if element == "material 0 \"Wood\" baseColorTexture"),
            "{e}"
        );
        assert!(e.to_string().contains("texCoord 1"), "{e}");
    }

    fn fixture_write(dir: &Path, name: &str, bytes: &[u8]) {
        super::super::gltf_fixture::write(dir, name, bytes);
    }
}
