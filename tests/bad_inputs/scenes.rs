//! The scene families of the corpus: glTF (and GLB), OBJ / MTL, and the `.toml` scene
//! description.

use super::*;

// ---------------------------------------------------------------------------------------------
// glTF

/// The base glTF document: one textured quad (positions, normals, uvs, u16 indices), a camera
/// and a point light (KHR_lights_punctual), its buffer in `scene.bin`, its texture `tex.png`.
pub(super) fn gltf_base() -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    let f32s = |bin: &mut Vec<u8>, v: &[f32]| bin.extend(v.iter().flat_map(|f| f.to_le_bytes()));
    f32s(&mut bin, &[-1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0]);
    f32s(&mut bin, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    f32s(&mut bin, &[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
    bin.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    assert_eq!(bin.len(), 140);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"camera": 0, "translation": [0.0, 0.0, 3.0]},
            {"translation": [0.0, 0.0, 2.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0
        }]}],
        "materials": [{
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0}, "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0, "roughnessFactor": 1.0
            },
            "emissiveFactor": [0.0, 0.0, 0.0]
        }],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"uri": "tex.png"}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 100.0, "aspectRatio": 1.0}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1.0, 1.0, 1.0], "intensity": 50.0}]}},
        "buffers": [{"uri": "scene.bin", "byteLength": 140}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    (doc, bin)
}

pub(super) fn png_bytes(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 128]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// Sets (`Some`) or removes (`None`) the value at JSON pointer `at`, which must exist.
pub(super) fn edit(doc: &mut Value, at: &str, value: Option<Value>) {
    let (parent, key) = at.rsplit_once('/').unwrap();
    let parent = if parent.is_empty() { &mut *doc } else { doc.pointer_mut(parent).unwrap_or_else(|| panic!("{at}")) };
    match (parent, value) {
        (Value::Object(map), Some(v)) => {
            map.insert(key.to_string(), v);
        }
        (Value::Object(map), None) => {
            map.remove(key).unwrap_or_else(|| panic!("{at}"));
        }
        (Value::Array(items), Some(v)) => items[key.parse::<usize>().unwrap()] = v,
        (Value::Array(items), None) => {
            items.remove(key.parse::<usize>().unwrap());
        }
        _ => panic!("{at}: not in an object or array"),
    }
}

/// A glTF case folder: `scene.gltf` from `doc`, `scene.bin`, `tex.png`.
pub(super) fn write_gltf(dir: &Path, doc: &Value, bin: &[u8]) -> PathBuf {
    std::fs::write(dir.join("scene.bin"), bin).unwrap();
    std::fs::write(dir.join("tex.png"), png_bytes(4, 4)).unwrap();
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
    path
}

/// The same scene as one `.glb` (JSON chunk + BIN chunk).
pub(super) fn glb_bytes(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut doc = doc.clone();
    edit(&mut doc, "/buffers/0/uri", None);
    let mut js = serde_json::to_vec(&doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + js.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&js);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

pub(super) fn render_args(scene: &Path, dir: &Path) -> Vec<OsString> {
    let mut a = vec![OsString::from("render"), p(scene), "--out".into(), p(&dir.join("out.exr"))];
    a.extend(os(&["--width", "8", "--height", "8", "--spp", "1"]));
    a
}

pub(super) fn gltf_cases() -> Vec<Case> {
    let (base, bin) = gltf_base();
    let dir = case_dir("gltf", "base");
    let scene = write_gltf(&dir, &base, &bin);
    run_ok(evsim(), &render_args(&scene, &dir));
    let glb_dir = case_dir("gltf", "base-glb");
    let glb = glb_dir.join("scene.glb");
    std::fs::write(&glb, glb_bytes(&base, &bin)).unwrap();
    std::fs::write(glb_dir.join("tex.png"), png_bytes(4, 4)).unwrap();
    run_ok(evsim(), &render_args(&glb, &glb_dir));

    let mut cases = Vec::new();
    let mut add = |name: String, doc: &Value, bin: &[u8], names: &[&str], tex: Option<&[u8]>| {
        let dir = case_dir("gltf", &name);
        let scene = write_gltf(&dir, doc, bin);
        if let Some(tex) = tex {
            std::fs::write(dir.join("tex.png"), tex).unwrap();
        }
        // a texture's errors name the texture file (and the material), the others the scene file
        let mut must_name: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        if must_name.is_empty() {
            must_name.push("scene.gltf".into());
        }
        cases.push(Case { family: "gltf", name, exe: evsim(), args: render_args(&scene, &dir), must_name });
    };
    // Index references out of range, negative, of the wrong type.
    let refs = [
        "/meshes/0/primitives/0/attributes/POSITION",
        "/meshes/0/primitives/0/attributes/NORMAL",
        "/meshes/0/primitives/0/attributes/TEXCOORD_0",
        "/meshes/0/primitives/0/indices",
        "/meshes/0/primitives/0/material",
        "/nodes/0/mesh",
        "/nodes/1/camera",
        "/nodes/2/extensions/KHR_lights_punctual/light",
        "/scenes/0/nodes/0",
        "/scene",
        "/accessors/0/bufferView",
        "/accessors/3/bufferView",
        "/bufferViews/0/buffer",
        "/textures/0/source",
        "/textures/0/sampler",
        "/materials/0/pbrMetallicRoughness/baseColorTexture/index",
    ];
    for at in refs {
        for v in [json!(99), json!(-1), json!("x"), json!(1.5)] {
            let mut doc = base.clone();
            edit(&mut doc, at, Some(v.clone()));
            add(format!("{at} = {v}"), &doc, &bin, &[], None);
        }
    }
    // Required fields removed.
    let required = [
        "/asset",
        "/asset/version",
        "/buffers/0/byteLength",
        "/buffers/0/uri",
        "/accessors/0/count",
        "/accessors/0/componentType",
        "/accessors/0/type",
        "/bufferViews/0/byteLength",
        "/meshes/0/primitives",
        "/meshes/0/primitives/0/attributes",
        "/meshes/0/primitives/0/attributes/POSITION",
        "/images/0/uri",
        "/cameras/0/perspective",
        "/cameras/0/perspective/yfov",
        "/cameras/0/type",
        "/extensions/KHR_lights_punctual/lights/0/type",
    ];
    for at in required {
        let mut doc = base.clone();
        edit(&mut doc, at, None);
        add(format!("{at} removed"), &doc, &bin, &[], None);
    }
    // Values out of the specification (or of what we can render).
    let light = "/extensions/KHR_lights_punctual/lights/0";
    let pbr = "/materials/0/pbrMetallicRoughness";
    let values: Vec<(String, Value)> = vec![
        ("/accessors/0/count".into(), json!(1_000_000_000u64)),
        ("/accessors/0/count".into(), json!(0)),
        ("/accessors/0/byteOffset".into(), json!(1000)),
        ("/bufferViews/0/byteLength".into(), json!(100_000)),
        ("/bufferViews/1/byteOffset".into(), json!(100_000)),
        ("/buffers/0/byteLength".into(), json!(100_000)),
        ("/accessors/0/componentType".into(), json!(9999)),
        ("/accessors/0/componentType".into(), json!(5121)),
        ("/accessors/0/type".into(), json!("VEC7")),
        ("/accessors/0/type".into(), json!("VEC2")),
        ("/accessors/3/type".into(), json!("VEC3")),
        ("/accessors/3/componentType".into(), json!(5126)),
        ("/cameras/0/perspective/yfov".into(), json!(0.0)),
        ("/cameras/0/perspective/yfov".into(), json!(-1.0)),
        ("/cameras/0/perspective/yfov".into(), json!(4.0)),
        ("/cameras/0/perspective/yfov".into(), json!("x")),
        ("/cameras/0/perspective/znear".into(), json!(0.0)),
        ("/cameras/0/perspective/znear".into(), json!(-1.0)),
        ("/cameras/0/perspective/zfar".into(), json!(0.01)),
        ("/cameras/0/perspective/aspectRatio".into(), json!(0.0)),
        ("/cameras/0/perspective/aspectRatio".into(), json!(-1.0)),
        ("/cameras/0/type".into(), json!("fisheye")),
        ("/asset/version".into(), json!("1.0")),
        ("/asset/version".into(), json!("3.0")),
        ("/asset/version".into(), json!("two")),
        (format!("{light}/intensity"), json!(-1.0)),
        (format!("{light}/intensity"), json!("x")),
        (format!("{light}/type"), json!("laser")),
        (format!("{light}/color"), json!([1.0, 1.0])),
        (format!("{light}/color"), json!([-1.0, 1.0, 1.0])),
        (format!("{light}/range"), json!(-1.0)),
        ("/nodes/0/matrix".into(), json!([1.0, 0.0, 0.0])),
        ("/nodes/0/translation".into(), json!([0.0, 0.0])),
        ("/nodes/0/rotation".into(), json!([0.0, 0.0, 0.0])),
        ("/nodes/0/scale".into(), json!("x")),
        ("/nodes/0/children".into(), json!([0])),
        ("/nodes/0/children".into(), json!([99])),
        (format!("{pbr}/baseColorFactor"), json!([1.0, 1.0, 1.0])),
        (format!("{pbr}/baseColorFactor"), json!([-1.0, 1.0, 1.0, 1.0])),
        (format!("{pbr}/metallicFactor"), json!(2.0)),
        (format!("{pbr}/metallicFactor"), json!(-1.0)),
        (format!("{pbr}/roughnessFactor"), json!(-1.0)),
        ("/materials/0/emissiveFactor".into(), json!([-1.0, 0.0, 0.0])),
        ("/materials/0/emissiveFactor".into(), json!([1.0, 1.0])),
        (format!("{pbr}/baseColorTexture/texCoord"), json!(5)),
        ("/samplers/0/wrapS".into(), json!(1234)),
        ("/samplers/0/magFilter".into(), json!(1)),
        ("/images/0/uri".into(), json!("missing.png")),
        ("/images/0/uri".into(), json!("data:image/png;base64,!!!")),
        ("/buffers/0/uri".into(), json!("missing.bin")),
        ("/buffers/0/uri".into(), json!("data:application/octet-stream;base64,@@@")),
        ("/meshes/0/primitives/0/mode".into(), json!(99)),
        ("/scenes".into(), json!([])),
        ("/extensionsRequired".into(), json!(["KHR_no_such_extension"])),
        ("/materials/0/extensions".into(), json!({"KHR_materials_emissive_strength": {"emissiveStrength": -1.0}})),
    ];
    for (at, v) in values {
        let mut doc = base.clone();
        edit(&mut doc, &at, Some(v.clone()));
        add(format!("{at} = {v}"), &doc, &bin, &[], None);
    }
    // A spot light with its cones the wrong way round, or wider than a hemisphere.
    for (inner, outer) in [(1.0, 0.5), (0.1, 2.0), (-0.5, 0.5)] {
        let mut doc = base.clone();
        edit(&mut doc, &format!("{light}/type"), Some(json!("spot")));
        edit(&mut doc, &format!("{light}/spot"), Some(json!({"innerConeAngle": inner, "outerConeAngle": outer})));
        add(format!("spot cones {inner} {outer}"), &doc, &bin, &[], None);
    }
    // Bad buffer contents: indices past the vertices, NaN positions, a short buffer.
    let mut far = bin.clone();
    far[128..130].copy_from_slice(&999u16.to_le_bytes());
    add("index 999 of 4 vertices".into(), &base, &far, &[], None);
    let mut nan = bin.clone();
    nan[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    add("NaN position".into(), &base, &nan, &[], None);
    let mut inf = bin.clone();
    inf[52..56].copy_from_slice(&f32::INFINITY.to_le_bytes());
    add("infinite normal".into(), &base, &inf, &[], None);
    add("buffer of 100 bytes".into(), &base, &bin[..100], &[], None);
    add("empty buffer".into(), &base, &[], &[], None);
    // Bad texture files.
    let tex = png_bytes(4, 4);
    add("texture truncated".into(), &base, &bin, &["tex.png", "material 0"], Some(&tex[..tex.len() / 2]));
    add("texture not a PNG".into(), &base, &bin, &["tex.png", "material 0"], Some(b"this is not an image"));
    add("texture empty".into(), &base, &bin, &["tex.png", "material 0"], Some(&[]));
    // Broken JSON text.
    let text = serde_json::to_vec_pretty(&base).unwrap();
    for (name, bytes) in [
        ("json cut at 10%", text[..text.len() / 10].to_vec()),
        ("json cut at 50%", text[..text.len() / 2].to_vec()),
        ("json cut at 99%", text[..text.len() - 3].to_vec()),
        ("json empty", Vec::new()),
        ("json array", b"[]".to_vec()),
        ("json binary junk", (0..200u32).map(|i| (i * 37 % 251) as u8).collect()),
    ] {
        let dir = case_dir("gltf", name);
        let scene = write_gltf(&dir, &base, &bin);
        std::fs::write(&scene, bytes).unwrap();
        let args = render_args(&scene, &dir);
        cases.push(Case {
            family: "gltf",
            name: name.into(),
            exe: evsim(),
            args,
            must_name: vec!["scene.gltf".into()],
        });
    }
    // Broken GLB containers.
    let good = glb_bytes(&base, &bin);
    let mut glbs: Vec<(&str, Vec<u8>)> = vec![
        ("glb cut at 10%", good[..good.len() / 10].to_vec()),
        ("glb cut at 50%", good[..good.len() / 2].to_vec()),
        ("glb cut before the BIN chunk", good[..good.len() - 140 - 8].to_vec()),
        ("glb header only", good[..12].to_vec()),
    ];
    let mut magic = good.clone();
    magic[0] = b'x';
    glbs.push(("glb wrong magic", magic));
    let mut version = good.clone();
    version[4] = 1;
    glbs.push(("glb version 1", version));
    let mut length = good.clone();
    length[8..12].copy_from_slice(&(10 * good.len() as u32).to_le_bytes());
    glbs.push(("glb length past the end", length));
    let mut chunk = good.clone();
    chunk[12..16].copy_from_slice(&(10 * good.len() as u32).to_le_bytes());
    glbs.push(("glb JSON chunk past the end", chunk));
    for (name, bytes) in glbs {
        let dir = case_dir("gltf", name);
        let scene = dir.join("scene.glb");
        std::fs::write(&scene, bytes).unwrap();
        std::fs::write(dir.join("tex.png"), &tex).unwrap();
        let args = render_args(&scene, &dir);
        cases.push(Case { family: "gltf", name: name.into(), exe: evsim(), args, must_name: vec!["scene.glb".into()] });
    }
    cases
}

// ---------------------------------------------------------------------------------------------
// OBJ / MTL

pub(super) const OBJ: &str = "mtllib scene.mtl
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl wall
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
v -0.2 -0.2 1
v 0.2 -0.2 1
v 0 0.2 1
usemtl lamp
f 5 6 7
";

pub(super) const MTL: &str = "newmtl wall
Kd 0.8 0.8 0.8
map_Kd tex.png
newmtl lamp
Kd 0 0 0
Ke 5 5 5
";

pub(super) fn obj_cases() -> Vec<Case> {
    let write = |name: &str, obj: &str, mtl: &str, tex: &[u8]| {
        let dir = case_dir("obj", name);
        std::fs::write(dir.join("scene.obj"), obj).unwrap();
        std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
        std::fs::write(dir.join("tex.png"), tex).unwrap();
        let mut args = render_args(&dir.join("scene.obj"), &dir);
        args.extend(os(&["--look-from", "0,0,3", "--look-at", "0,0,0"]));
        args
    };
    let tex = png_bytes(4, 4);
    run_ok(evsim(), &write("base", OBJ, MTL, &tex));
    let mut cases = Vec::new();
    let obj_edits: &[(&str, &str, &str)] = &[
        ("face index past the vertices", "f 5 6 7", "f 5 6 99"),
        ("face index 0", "f 5 6 7", "f 0 6 7"),
        ("relative index before the first vertex", "f 5 6 7", "f -99 6 7"),
        ("texture index past the vts", "f 1/1/1 2/2/1 3/3/1", "f 1/99/1 2/2/1 3/3/1"),
        ("normal index past the vns", "f 1/1/1 2/2/1 3/3/1", "f 1/1/99 2/2/1 3/3/1"),
        ("face of two vertices", "f 5 6 7", "f 5 6"),
        ("vertex not a number", "v -1 -1 0", "v a b c"),
        ("vertex NaN", "v -1 -1 0", "v nan 0 0"),
        ("vertex infinite", "v -1 -1 0", "v inf 0 0"),
        ("vertex of two coordinates", "v -1 -1 0", "v -1 -1"),
        ("texture coordinate NaN", "vt 0 0", "vt nan 0"),
        ("normal NaN", "vn 0 0 1", "vn nan 0 1"),
        ("missing MTL library", "mtllib scene.mtl", "mtllib missing.mtl"),
        ("undefined material", "usemtl lamp", "usemtl nosuch"),
        ("no geometry", OBJ, "mtllib scene.mtl\n"),
    ];
    for (name, from, to) in obj_edits {
        assert!(OBJ.contains(from), "{name}");
        let args = write(name, &OBJ.replacen(from, to, 1), MTL, &tex);
        cases.push(Case {
            family: "obj",
            name: name.to_string(),
            exe: evsim(),
            args,
            must_name: vec!["scene.obj".into()],
        });
    }
    // An OBJ without texture coordinates whose faces use them.
    let no_vt: String = OBJ.lines().filter(|l| !l.starts_with("vt ")).map(|l| format!("{l}\n")).collect();
    let no_vt = no_vt.replace("f 1/1/1 2/2/1 3/3/1", "f 1/1 2/2 3/3");
    let args = write("faces use vts of a file with none", &no_vt, MTL, &tex);
    cases.push(Case {
        family: "obj",
        name: "faces use vts of a file with none".into(),
        exe: evsim(),
        args,
        must_name: vec!["scene.obj".into()],
    });
    let mtl_edits: &[(&str, &str, &str)] = &[
        ("missing texture", "map_Kd tex.png", "map_Kd missing.png"),
        ("colour not a number", "Kd 0.8 0.8 0.8", "Kd x y z"),
        ("negative colour", "Kd 0.8 0.8 0.8", "Kd -1 0.8 0.8"),
        ("NaN emission", "Ke 5 5 5", "Ke nan 5 5"),
        ("negative emission", "Ke 5 5 5", "Ke -5 5 5"),
        ("colour of two numbers", "Kd 0.8 0.8 0.8", "Kd 0.8 0.8"),
    ];
    for (name, from, to) in mtl_edits {
        assert!(MTL.contains(from), "{name}");
        let args = write(name, OBJ, &MTL.replacen(from, to, 1), &tex);
        let file = if name.contains("texture") { "missing.png" } else { "scene.mtl" };
        cases.push(Case { family: "obj", name: name.to_string(), exe: evsim(), args, must_name: vec![file.into()] });
    }
    for (name, t) in [("texture truncated", &tex[..tex.len() / 2]), ("texture not a PNG", &b"not an image"[..])] {
        let args = write(name, OBJ, MTL, t);
        cases.push(Case { family: "obj", name: name.into(), exe: evsim(), args, must_name: vec!["tex.png".into()] });
    }
    let junk: String = (0..300u32).map(|i| char::from_u32(33 + i * 7 % 90).unwrap()).collect();
    for (name, obj) in [("cut mid-line", OBJ[..OBJ.len() / 3 + 5].to_string()), ("junk", junk)] {
        let args = write(name, &obj, MTL, &tex);
        cases.push(Case { family: "obj", name: name.into(), exe: evsim(), args, must_name: vec!["scene.obj".into()] });
    }
    cases
}

// ---------------------------------------------------------------------------------------------
// The .toml scene description (through `evsim dataset`)

pub(super) const SCENE_TOML: &str = r#"scene = "scene.gltf"

[camera]
origin = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
fov = 40.0
fov_axis = "y"

[environment]
type = "constant"
radiance = [0.1, 0.1, 0.1]

[trajectory]
type = "fast_motion"
target = [0.0, 0.0, 0.0]
radius = 3.0
height = 0.2
start_azimuth_deg = -10.0
sweep_deg = 10.0
bob = 0.1
duration = 0.02

[dataset]
width = 12
height = 8
spp = 1
sharp_spp = 1
views = 2
first_view_ms = 5.0
exposure_ms = 4.0
"#;

/// Every leaf of a TOML table as (dotted path, value).
pub(super) fn leaves(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in table {
        let path = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match v {
            toml::Value::Table(t) => leaves(&path, t, out),
            _ => out.push((path, v.clone())),
        }
    }
}

/// Tables of a TOML table as dotted paths ("" for the root).
pub(super) fn tables(prefix: &str, table: &toml::Table, out: &mut Vec<String>) {
    out.push(prefix.to_string());
    for (k, v) in table {
        if let toml::Value::Table(t) = v {
            tables(&if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") }, t, out);
        }
    }
}

pub(super) fn set_path(table: &mut toml::Table, path: &str, value: Option<toml::Value>) {
    let mut parts: Vec<&str> = path.split('.').collect();
    let last = parts.pop().unwrap();
    let mut t = table;
    for part in parts {
        t = t.get_mut(part).and_then(toml::Value::as_table_mut).unwrap_or_else(|| panic!("{path}"));
    }
    match value {
        Some(v) => {
            t.insert(last.to_string(), v);
        }
        None => {
            t.remove(last);
        }
    }
}

/// Wrong-type and NaN versions of a leaf (all invalid for any field of ours).
pub(super) fn bad_values(v: &toml::Value) -> Vec<toml::Value> {
    use toml::Value as T;
    match v {
        T::Float(_) => vec![T::String("x".into()), T::Float(f64::NAN), T::Float(f64::INFINITY)],
        T::Integer(_) => vec![T::String("x".into()), T::Float(0.5), T::Integer(-1)],
        T::String(_) => vec![T::Integer(5), T::String("no-such-value".into())],
        T::Boolean(_) => vec![T::String("x".into())],
        T::Array(items) => {
            let mut shorter = items.clone();
            shorter.pop();
            let mut nan = items.clone();
            if let Some(T::Float(_)) = nan.first() {
                nan[0] = T::Float(f64::NAN);
            } else {
                nan.push(T::String("x".into()));
            }
            vec![T::Array(shorter), T::Array(nan), T::String("x".into())]
        }
        _ => Vec::new(),
    }
}

pub(super) fn scene_toml_cases() -> Vec<Case> {
    let (doc, bin) = gltf_base();
    let setup = |name: &str, text: &str| {
        let dir = case_dir("scene-toml", name);
        write_gltf(&dir, &doc, &bin);
        std::fs::write(dir.join("scene.toml"), text).unwrap();
        let mut args = vec![OsString::from("dataset"), p(&dir.join("scene.toml"))];
        args.extend(os(&["--quiet", "--set", "dataset.shading=path_traced"]));
        args.extend(["--out".into(), p(&dir.join("out"))]);
        args
    };
    run_ok(evsim(), &setup("base", SCENE_TOML));
    let base: toml::Table = SCENE_TOML.parse().unwrap();
    let mut cases = Vec::new();
    let mut leaf_list = Vec::new();
    leaves("", &base, &mut leaf_list);
    // Integers that may legitimately be negative; strings whose odd value is a path.
    let signed = ["trajectory.start_azimuth_deg", "trajectory.sweep_deg", "trajectory.height", "trajectory.bob"];
    for (path, v) in &leaf_list {
        for bad in bad_values(v) {
            if matches!(bad, toml::Value::Integer(-1)) && signed.contains(&path.as_str()) {
                continue;
            }
            let mut t = base.clone();
            set_path(&mut t, path, Some(bad.clone()));
            let name = format!("{path} = {bad}");
            let args = setup(&name, &toml::to_string(&t).unwrap());
            let field = path.rsplit('.').next().unwrap().to_string();
            let file = if path == "scene" { "scene" } else { "scene.toml" };
            cases.push(Case { family: "scene-toml", name, exe: evsim(), args, must_name: vec![file.into(), field] });
        }
    }
    let mut table_list = Vec::new();
    tables("", &base, &mut table_list);
    for table in table_list {
        let mut t = base.clone();
        let key = if table.is_empty() { "unknown_key".to_string() } else { format!("{table}.unknown_key") };
        set_path(&mut t, &key, Some(toml::Value::Integer(1)));
        let args = setup(&format!("{key} added"), &toml::to_string(&t).unwrap());
        let must_name = vec!["scene.toml".into(), "unknown_key".into()];
        cases.push(Case { family: "scene-toml", name: format!("{key} added"), exe: evsim(), args, must_name });
    }
    let ranges: &[(&str, toml::Value)] = &[
        ("camera.fov", 0.0.into()),
        ("camera.fov", 180.0.into()),
        ("camera.fov", (-5.0).into()),
        ("trajectory.duration", 0.0.into()),
        ("trajectory.duration", (-1.0).into()),
        ("trajectory.radius", 0.0.into()),
        ("dataset.width", 0.into()),
        ("dataset.height", 0.into()),
        ("dataset.spp", 0.into()),
        ("dataset.views", 0.into()),
        ("dataset.exposure_ms", 0.0.into()),
        ("dataset.exposure_ms", (-4.0).into()),
        ("dataset.exposure_ms", 1000.0.into()),
        ("dataset.first_view_ms", 1000.0.into()),
        ("environment.radiance", vec![-1.0, 0.1, 0.1].into()),
        ("camera.target", vec![0.0, 0.0, 3.0].into()),
    ];
    for (path, v) in ranges {
        let mut t = base.clone();
        set_path(&mut t, path, Some(v.clone()));
        let name = format!("{path} = {v}");
        let args = setup(&name, &toml::to_string(&t).unwrap());
        let field = path.rsplit('.').next().unwrap().to_string();
        cases.push(Case {
            family: "scene-toml",
            name,
            exe: evsim(),
            args,
            must_name: vec!["scene.toml".into(), field],
        });
    }
    for (name, text) in [
        ("scene removed", SCENE_TOML.replacen("scene = \"scene.gltf\"", "", 1)),
        ("scene file missing", SCENE_TOML.replacen("scene.gltf", "missing.gltf", 1)),
        ("broken line", format!("{SCENE_TOML}\nthis is not toml\n")),
        ("cut in a table header", SCENE_TOML[..SCENE_TOML.find("[trajectory]").unwrap() + 4].to_string()),
    ] {
        let args = setup(name, &text);
        let file = if name == "scene file missing" { "missing.gltf" } else { "scene.toml" };
        cases.push(Case { family: "scene-toml", name: name.into(), exe: evsim(), args, must_name: vec![file.into()] });
    }
    cases
}
