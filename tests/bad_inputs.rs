//! The bad-input corpus: a few hundred malformed inputs, generated below from valid ones, each
//! run through the command a user would type (`evsim render / dataset / check / events`,
//! `evtrain train / eval`, `evbench run`). Every case must end in a *clean error*: a non-zero
//! exit (not a panic's 101, not a signal), no "panicked" in the output, and a message that names
//! the file (and, where the case says so, the field). The families:
//!
//! - `gltf`: a small textured, lit glTF scene (and its `.glb` form) with an index out of range,
//!   a required field removed, an out-of-spec value, or a truncated / missing / corrupt file;
//! - `obj`: an OBJ + MTL scene with bad faces, numbers, materials and textures;
//! - `scene-toml`: the `.toml` scene description with every leaf given a wrong type or NaN, an
//!   unknown key in every table, and out-of-range values;
//! - `dataset`: a simulated dataset with a file deleted, truncated or replaced by an
//!   inconsistent one, each case run through both `evsim check` and `evtrain train`;
//! - `checkpoint`: a trained run whose `checkpoint.bin` or `config.toml` is truncated, flipped
//!   or deleted, through `evtrain eval` and `evtrain train --resume`;
//! - `train-set`: `evtrain train --set` with wrong types, NaN and impossible sizes;
//! - `matrix`: `evbench run --dry-run` on broken run-matrix files;
//! - `events`: `evsim events` on broken frame folders, timestamp files and settings.
//!
//! Each family first runs its valid base and requires it to succeed, so a case fails because
//! of its mutation. The test prints one line per family and a total, and fails listing every
//! case that panicked, aborted, succeeded, or gave an error that does not name the file.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use evblur_tests::{copy_dir, temp_dir, workspace_binary};
use rayon::prelude::*;
use serde_json::{json, Value};

/// One bad input: the command to run and the words its error must contain.
struct Case {
    family: &'static str,
    name: String,
    exe: &'static Path,
    args: Vec<OsString>,
    /// Every one of these must appear in the error output (file names, field names).
    must_name: Vec<String>,
}

/// How a case ended.
#[derive(Debug, PartialEq)]
enum Outcome {
    Clean,
    SilentSuccess,
    Panic,
    Abort(String),
    Unclear(Vec<String>),
}

fn evsim() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-simulator", "evsim"))
}

fn evtrain() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-trainer", "evtrain"))
}

fn evbench() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-benchmark", "evbench"))
}

fn root() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| temp_dir("bad", "inputs"))
}

/// A fresh folder for one case (or base) of a family.
fn case_dir(family: &str, name: &str) -> PathBuf {
    let safe: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    let dir = root().join(family).join(safe);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

fn p(path: &Path) -> OsString {
    path.as_os_str().to_owned()
}

/// Runs a command: (exit code or None for a signal, stdout + stderr).
fn run(exe: &Path, args: &[OsString]) -> (Option<i32>, String) {
    let out =
        Command::new(exe).args(args).env_remove("RUST_BACKTRACE").env_remove("RUST_LIB_BACKTRACE").output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.code(), text)
}

/// Runs a valid base command and fails the test unless it succeeds.
fn run_ok(exe: &Path, args: &[OsString]) {
    let (code, text) = run(exe, args);
    assert_eq!(code, Some(0), "base case {} {args:?} failed:\n{text}", exe.display());
}

fn classify(case: &Case) -> (Outcome, String) {
    let (code, text) = run(case.exe, &case.args);
    let outcome = match code {
        None => Outcome::Abort("killed by a signal".into()),
        _ if text.contains("panicked") => Outcome::Panic,
        Some(101) => Outcome::Panic,
        Some(0) => Outcome::SilentSuccess,
        Some(_) => {
            let missing: Vec<String> = case.must_name.iter().filter(|w| !text.contains(w.as_str())).cloned().collect();
            if missing.is_empty() {
                Outcome::Clean
            } else {
                Outcome::Unclear(missing)
            }
        }
    };
    (outcome, text)
}

// ---------------------------------------------------------------------------------------------
// glTF

/// The base glTF document: one textured quad (positions, normals, uvs, u16 indices), a camera
/// and a point light (KHR_lights_punctual), its buffer in `scene.bin`, its texture `tex.png`.
fn gltf_base() -> (Value, Vec<u8>) {
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

fn png_bytes(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 128]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// Sets (`Some`) or removes (`None`) the value at JSON pointer `at`, which must exist.
fn edit(doc: &mut Value, at: &str, value: Option<Value>) {
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
fn write_gltf(dir: &Path, doc: &Value, bin: &[u8]) -> PathBuf {
    std::fs::write(dir.join("scene.bin"), bin).unwrap();
    std::fs::write(dir.join("tex.png"), png_bytes(4, 4)).unwrap();
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
    path
}

/// The same scene as one `.glb` (JSON chunk + BIN chunk).
fn glb_bytes(doc: &Value, bin: &[u8]) -> Vec<u8> {
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

fn render_args(scene: &Path, dir: &Path) -> Vec<OsString> {
    let mut a = vec![OsString::from("render"), p(scene), "--out".into(), p(&dir.join("out.exr"))];
    a.extend(os(&["--width", "8", "--height", "8", "--spp", "1"]));
    a
}

fn gltf_cases() -> Vec<Case> {
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

const OBJ: &str = "mtllib scene.mtl
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

const MTL: &str = "newmtl wall
Kd 0.8 0.8 0.8
map_Kd tex.png
newmtl lamp
Kd 0 0 0
Ke 5 5 5
";

fn obj_cases() -> Vec<Case> {
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

const SCENE_TOML: &str = r#"scene = "scene.gltf"

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
fn leaves(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in table {
        let path = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match v {
            toml::Value::Table(t) => leaves(&path, t, out),
            _ => out.push((path, v.clone())),
        }
    }
}

/// Tables of a TOML table as dotted paths ("" for the root).
fn tables(prefix: &str, table: &toml::Table, out: &mut Vec<String>) {
    out.push(prefix.to_string());
    for (k, v) in table {
        if let toml::Value::Table(t) = v {
            tables(&if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") }, t, out);
        }
    }
}

fn set_path(table: &mut toml::Table, path: &str, value: Option<toml::Value>) {
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
fn bad_values(v: &toml::Value) -> Vec<toml::Value> {
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

fn scene_toml_cases() -> Vec<Case> {
    let (doc, bin) = gltf_base();
    let setup = |name: &str, text: &str| {
        let dir = case_dir("scene-toml", name);
        write_gltf(&dir, &doc, &bin);
        std::fs::write(dir.join("scene.toml"), text).unwrap();
        let mut args = vec![OsString::from("dataset"), p(&dir.join("scene.toml"))];
        args.extend(["--out".into(), p(&dir.join("out")), "--quiet".into(), "--shading".into(), "path-traced".into()]);
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

// ---------------------------------------------------------------------------------------------
// Datasets (through `evsim check` and `evtrain train`)

/// A small dataset of `scenes/tiny` (32x24, 1 spp), simulated once.
fn base_dataset() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = case_dir("dataset", "base");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml");
        let mut args = vec![OsString::from("dataset"), p(&scene), "--out".into(), p(&dir)];
        args.extend(os(&["--width", "32", "--height", "24", "--spp", "1", "--sharp-spp", "1", "--quiet"]));
        args.extend(os(&["--shading", "path-traced"]));
        run_ok(evsim(), &args);
        dir
    })
}

/// Small-model `evtrain train` flags: seconds per run.
const SMALL: &[&str] = &["--set", "model.coarse_volume.res=16", "--iterations", "1", "--quiet", "--threads", "1"];

fn train_args(data: &Path, preset: &str, out: &Path) -> Vec<OsString> {
    let mut a = vec![OsString::from("train"), "--data".into(), p(data), "--preset".into(), preset.into()];
    a.extend(["--out".into(), p(out)]);
    a.extend(os(SMALL));
    a
}

fn write_h5(path: &Path, columns: &[(&str, H5Column)]) {
    let _ = std::fs::remove_file(path);
    let file = rust_hdf5::H5File::create(path).unwrap();
    for (name, col) in columns {
        match col {
            H5Column::I64(v) => {
                file.new_dataset::<i64>().shape([v.len()]).create(name).unwrap().write_raw(v).unwrap();
            }
            H5Column::F64(v) => {
                file.new_dataset::<f64>().shape([v.len()]).create(name).unwrap().write_raw(v).unwrap();
            }
        }
    }
    file.close().unwrap();
}

enum H5Column {
    I64(Vec<i64>),
    F64(Vec<f64>),
}

/// The base dataset's events as columns (x, y, t, p).
fn base_events() -> [Vec<i64>; 4] {
    let file = rust_hdf5::H5File::open(base_dataset().join("events.h5")).unwrap();
    let col = |name: &str| -> Vec<i64> {
        let reader = simulator::dataset::EventColumnReader::open(&file, name).unwrap();
        let chunk = reader.read(0, reader.len()).unwrap();
        (0..reader.len()).map(|i| chunk.get(i) as i64).collect()
    };
    [col("x"), col("y"), col("t"), col("p")]
}

fn dataset_cases() -> Vec<Case> {
    let base = base_dataset();
    run_ok(evsim(), &[OsString::from("check"), p(base)]);
    run_ok(evtrain(), &train_args(base, "e-nerf", &case_dir("dataset", "base-run").join("run")));
    let mut cases = Vec::new();
    let mut add = |name: &str, file: &str, mutate: &dyn Fn(&Path)| {
        let dir = case_dir("dataset", name).join("data");
        copy_dir(base, &dir);
        mutate(&dir);
        let must_name = vec![file.to_string()];
        let check = vec![OsString::from("check"), p(&dir)];
        cases.push(Case { family: "dataset", name: format!("{name} (check)"), exe: evsim(), args: check, must_name });
        let args = train_args(&dir, "e-nerf", &dir.parent().unwrap().join("run"));
        let must_name = vec![file.to_string()];
        cases.push(Case { family: "dataset", name: format!("{name} (train)"), exe: evtrain(), args, must_name });
    };
    let files = [
        "dataset.toml",
        "events.h5",
        "poses_bounds.npy",
        "all_poses_bounds.npy",
        "all_timestamps.npy",
        "images_1/timestamps.npz",
        "images_1/03.png",
    ];
    for f in files {
        let name = f.rsplit('/').next().unwrap();
        // dataset.toml is optional (public datasets have none): only a broken one is bad
        if f != "dataset.toml" {
            add(&format!("{f} deleted"), name, &|d| std::fs::remove_file(d.join(f)).unwrap());
        }
        add(&format!("{f} emptied"), name, &|d| std::fs::write(d.join(f), b"").unwrap());
        add(&format!("{f} cut in half"), name, &|d| {
            let bytes = std::fs::read(d.join(f)).unwrap();
            std::fs::write(d.join(f), &bytes[..bytes.len() / 2]).unwrap();
        });
    }
    add("images_1 deleted", "images_1", &|d| std::fs::remove_dir_all(d.join("images_1")).unwrap());
    let manifest_edits: &[(&str, &str, &str, &str)] = &[
        ("manifest broken line", "\n", "\nthis is not toml\n", "dataset.toml"),
        ("manifest unknown key", "tool = ", "colour = 1\ntool = ", "colour"),
        ("manifest threshold NaN", "c_pos = ", "c_pos = nan\n#", "c_pos"),
        ("manifest views 10", "views = 9\n", "views = 10\n", "views"),
        ("manifest width 64", "width = 32", "width = 64", "width"),
    ];
    for &(name, from, to, field) in manifest_edits {
        add(name, field, &|d| {
            let text = std::fs::read_to_string(d.join("dataset.toml")).unwrap();
            assert!(text.contains(from), "{name}: {from:?} not in the manifest");
            std::fs::write(d.join("dataset.toml"), text.replacen(from, to, 1)).unwrap();
        });
    }
    add("image of another size", "03.png", &|d| std::fs::write(d.join("images_1/03.png"), png_bytes(16, 12)).unwrap());
    add("image not a PNG", "03.png", &|d| std::fs::write(d.join("images_1/03.png"), b"not a png").unwrap());
    add("image 16-bit", "03.png", &|d| {
        image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(32, 24, image::Rgb([1000u16, 2000, 3000]))
            .save(d.join("images_1/03.png"))
            .unwrap();
    });
    add("image removed from the middle", "images_1", &|d| {
        std::fs::remove_file(d.join("images_1/04.png")).unwrap();
        std::fs::rename(d.join("images_1/08.png"), d.join("images_1/04.png")).unwrap();
    });
    let npy = |rows: usize, cols: usize, fill: f32| {
        let data: Vec<f32> = (0..rows * cols).map(|i| if i == 3 { fill } else { 1.0 + i as f32 }).collect();
        (rows, cols, data)
    };
    for (name, (rows, cols, data)) in [
        ("poses of 8 rows", npy(8, 17, 1.0)),
        ("poses of 15 columns", npy(9, 15, 1.0)),
        ("poses with a NaN", npy(9, 17, f32::NAN)),
    ] {
        add(name, "poses_bounds.npy", &|d| {
            evblur_tests::write_npy_f32(&d.join("poses_bounds.npy"), &[rows, cols], &data);
        });
    }
    add("all_timestamps with a NaN", "all_timestamps.npy", &|d| {
        let n = simulator::npy::read_npy(&d.join("all_timestamps.npy")).unwrap().shape()[0];
        let t: Vec<f32> = (0..n).map(|i| if i == 5 { f32::NAN } else { 1000.0 * (i + 1) as f32 }).collect();
        evblur_tests::write_npy_f32(&d.join("all_timestamps.npy"), &[n], &t);
    });
    add("timestamps going back", "timestamps.npz", &|d| {
        let path = d.join("images_1/timestamps.npz");
        let mut arrays = simulator::npy::read_npz(&path).unwrap();
        for (_, a) in arrays.iter_mut() {
            let mut v = a.data().to_f64();
            v.swap(2, 5);
            *a = simulator::npy::NpyArray::vector(v);
        }
        let refs: Vec<(&str, simulator::npy::NpyArray)> = arrays.iter().map(|(k, a)| (k.as_str(), a.clone())).collect();
        simulator::npy::write_npz(&path, &refs).unwrap();
    });
    add("timestamps without timestamps_start", "timestamps_start", &|d| {
        let path = d.join("images_1/timestamps.npz");
        let arrays = simulator::npy::read_npz(&path).unwrap();
        let refs: Vec<(&str, simulator::npy::NpyArray)> =
            arrays.iter().filter(|(k, _)| k != "timestamps_start").map(|(k, a)| (k.as_str(), a.clone())).collect();
        simulator::npy::write_npz(&path, &refs).unwrap();
    });
    // Event files with broken contents.
    let [x, y, t, pol] = base_events();
    let n = x.len();
    assert!(n > 100, "the base dataset has {n} events");
    type EventEdit = Box<dyn Fn(&mut [Vec<i64>; 4])>;
    let event_edits: Vec<(&str, &str, EventEdit)> = vec![
        ("polarity 7", "p", Box::new(|c| c[3][10] = 7)),
        ("polarity 2 everywhere", "p", Box::new(|c| c[3].iter_mut().for_each(|v| *v = 2))),
        ("times going back", "t", Box::new(|c| c[2].swap(10, 60))),
        ("x past the image", "x", Box::new(|c| c[0][10] = 32)),
        ("negative y", "y", Box::new(|c| c[1][10] = -1)),
    ];
    for (name, field, e) in event_edits {
        let mut cols = [x.clone(), y.clone(), t.clone(), pol.clone()];
        e(&mut cols);
        add(name, field, &|d| {
            let c = cols.clone();
            let named = [("x", c[0].clone()), ("y", c[1].clone()), ("t", c[2].clone()), ("p", c[3].clone())];
            let columns: Vec<(&str, H5Column)> = named.into_iter().map(|(k, v)| (k, H5Column::I64(v))).collect();
            write_h5(&d.join("events.h5"), &columns);
        });
    }
    add("event time NaN", "t", &|d| {
        let mut tf: Vec<f64> = t.iter().map(|&v| v as f64).collect();
        tf[10] = f64::NAN;
        let columns = vec![
            ("x", H5Column::I64(x.clone())),
            ("y", H5Column::I64(y.clone())),
            ("t", H5Column::F64(tf)),
            ("p", H5Column::I64(pol.clone())),
        ];
        write_h5(&d.join("events.h5"), &columns);
    });
    add("event column p missing", "p", &|d| {
        let columns =
            vec![("x", H5Column::I64(x.clone())), ("y", H5Column::I64(y.clone())), ("t", H5Column::I64(t.clone()))];
        write_h5(&d.join("events.h5"), &columns);
    });
    add("event columns of different lengths", "events.h5", &|d| {
        let columns = vec![
            ("x", H5Column::I64(x.clone())),
            ("y", H5Column::I64(y.clone())),
            ("t", H5Column::I64(t.clone())),
            ("p", H5Column::I64(pol[..n - 1].to_vec())),
        ];
        write_h5(&d.join("events.h5"), &columns);
    });
    cases
}

// ---------------------------------------------------------------------------------------------
// Checkpoints and run folders (through `evtrain eval` and `evtrain train --resume`)

fn checkpoint_cases() -> Vec<Case> {
    let base_run = case_dir("checkpoint", "base").join("run");
    run_ok(evtrain(), &train_args(base_dataset(), "nerf", &base_run));
    let eval = |run: &Path| vec![OsString::from("eval"), p(run), "--threads".into(), "1".into()];
    run_ok(evtrain(), &eval(&base_run));
    let bytes = std::fs::read(base_run.join("checkpoint.bin")).unwrap();
    let len = bytes.len();
    let mut cases = Vec::new();
    let mut add = |name: String, file: &str, mutate: &dyn Fn(&Path)| {
        // a run folder each: eval and resume lock the run, and the cases run in parallel
        let [run, resumed] = ["eval", "resume"].map(|k| case_dir("checkpoint", &format!("{name} {k}")).join("run"));
        for r in [&run, &resumed] {
            copy_dir(&base_run, r);
            mutate(r);
        }
        let must_name = vec![file.to_string()];
        cases.push(Case {
            family: "checkpoint",
            name: format!("{name} (eval)"),
            exe: evtrain(),
            args: eval(&run),
            must_name,
        });
        let run = resumed;
        let mut resume = vec![OsString::from("train"), "--resume".into(), "--out".into(), p(&run)];
        resume.extend(os(&["--iterations", "2", "--quiet", "--threads", "1"]));
        let must_name = vec![file.to_string()];
        cases.push(Case {
            family: "checkpoint",
            name: format!("{name} (resume)"),
            exe: evtrain(),
            args: resume,
            must_name,
        });
    };
    for cut in [0, 1, 7, 8, 16, 64, len / 2, len - 1] {
        let b = bytes[..cut].to_vec();
        add(format!("checkpoint cut at {cut}"), "checkpoint.bin", &move |r| {
            std::fs::write(r.join("checkpoint.bin"), &b).unwrap()
        });
    }
    for k in 0..12 {
        let at = [0, 3, 8, 12, 20, 40][k % 6] + (k / 6) * (len / 2);
        let mut b = bytes.clone();
        b[at.min(len - 1)] ^= 0x10;
        add(format!("checkpoint byte {at} flipped"), "checkpoint.bin", &move |r| {
            std::fs::write(r.join("checkpoint.bin"), &b).unwrap()
        });
    }
    let mut longer = bytes.clone();
    longer.push(0);
    add("checkpoint one byte longer".into(), "checkpoint.bin", &move |r| {
        std::fs::write(r.join("checkpoint.bin"), &longer).unwrap()
    });
    add("checkpoint deleted".into(), "checkpoint.bin", &|r| std::fs::remove_file(r.join("checkpoint.bin")).unwrap());
    let config_edits: &[(&str, &str)] =
        &[("config broken line", "this is not toml\n"), ("config unknown key", "no_such_setting = 1\n")];
    for &(name, line) in config_edits {
        add(name.into(), "config.toml", &move |r| {
            let text = std::fs::read_to_string(r.join("config.toml")).unwrap();
            std::fs::write(r.join("config.toml"), format!("{line}{text}")).unwrap();
        });
    }
    add("config batch_rays 0".into(), "batch_rays", &|r| {
        let text = std::fs::read_to_string(r.join("config.toml")).unwrap();
        let edited: String = text
            .lines()
            .map(|l| if l.starts_with("batch_rays = ") { "batch_rays = 0".to_string() } else { l.to_string() })
            .map(|l| l + "\n")
            .collect();
        assert_ne!(edited, text);
        std::fs::write(r.join("config.toml"), edited).unwrap();
    });
    add("config.toml deleted".into(), "config.toml", &|r| std::fs::remove_file(r.join("config.toml")).unwrap());
    cases
}

// ---------------------------------------------------------------------------------------------
// `evtrain train --set`

fn train_set_cases() -> Vec<Case> {
    let shown = run(evtrain(), &os(&["presets", "--show", "e-nerf"]));
    assert_eq!(shown.0, Some(0), "{}", shown.1);
    let config: toml::Table = shown.1.parse().unwrap();
    let mut leaf_list = Vec::new();
    leaves("", &config, &mut leaf_list);
    let mut cases = Vec::new();
    let mut add = |name: String, sets: Vec<String>, field: &str| {
        let dir = case_dir("train-set", &name);
        let mut args = train_args(base_dataset(), "e-nerf", &dir.join("run"));
        for s in sets {
            args.extend(["--set".into(), s.into()]);
        }
        let must_name = vec![field.to_string()];
        cases.push(Case { family: "train-set", name, exe: evtrain(), args, must_name });
    };
    // Settings whose any value of the right type is valid; `iterations` and friends are given
    // on the command line by the corpus itself.
    let skip = ["iterations", "seed", "threads", "model.coarse_volume.res"];
    for (path, v) in &leaf_list {
        if skip.contains(&path.as_str()) {
            continue;
        }
        let bads: Vec<String> = match v {
            toml::Value::Float(_) => vec!["x".into(), "nan".into(), "inf".into()],
            toml::Value::Integer(_) => vec!["x".into(), "-1".into()],
            toml::Value::Boolean(_) => vec!["7".into()],
            toml::Value::String(_) => vec!["no-such-value".into(), "5".into()],
            toml::Value::Array(_) => vec!["[\"x\"]".into(), "3".into()],
            _ => Vec::new(),
        };
        for bad in bads {
            let field = path.rsplit('.').next().unwrap();
            add(format!("{path}={bad}"), vec![format!("{path}={bad}")], field);
        }
    }
    for (set, field) in [
        ("model.coarse_volume.res=100000", "res"),
        ("model.coarse_volume.res=0", "res"),
        ("model.coarse_volume.comps=[0, 16, 16]", "comps"),
        ("model.coarse.density_hidden=[1000000000]", "GB of memory"),
        ("batch_rays=1000000000000", "batch_rays"),
        ("batch_rays=0", "batch_rays"),
        ("model.n_coarse=0", "n_coarse"),
        ("model.bounds=[[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]]", "bounds"),
        ("no.such.setting=1", "no.such.setting"),
        ("model=3", "model"),
        ("adam.lr_volume=-1.0", "lr_volume"),
        ("events.batch=0", "batch"),
    ] {
        add(set.into(), vec![set.into()], field);
    }
    cases
}

// ---------------------------------------------------------------------------------------------
// `evbench run --dry-run`

fn matrix_cases() -> Vec<Case> {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml");
    let scene = scene.canonicalize().unwrap();
    let text = format!(
        "scale = \"cpu\"\nseeds = [0]\niterations = 10\nresults = \"results\"\n\n[dataset]\nwidth = 32\nheight = 24\n\n\
         [[methods]]\npreset = \"nerf\"\nname = \"nerf-small\"\nset = [\"batch_rays=256\"]\n\n[[scenes]]\nscene = {:?}\n",
        scene.to_str().unwrap()
    );
    let setup = |name: &str, text: &str| {
        let dir = case_dir("matrix", name);
        std::fs::write(dir.join("matrix.toml"), text).unwrap();
        vec![OsString::from("run"), p(&dir.join("matrix.toml")), "--dry-run".into()]
    };
    run_ok(evbench(), &setup("base", &text));
    let base: toml::Table = text.parse().unwrap();
    let mut leaf_list = Vec::new();
    leaves("", &base, &mut leaf_list);
    let mut cases = Vec::new();
    let mut add = |name: String, t: &toml::Table, field: &str| {
        let args = setup(&name, &toml::to_string(t).unwrap());
        let must_name = vec!["matrix.toml".to_string(), field.to_string()];
        cases.push(Case { family: "matrix", name, exe: evbench(), args, must_name });
    };
    for (path, v) in &leaf_list {
        for bad in bad_values(v) {
            if path == "results" && matches!(bad, toml::Value::String(_)) {
                continue; // any folder name is valid
            }
            let mut t = base.clone();
            set_path(&mut t, path, Some(bad.clone()));
            add(format!("{path} = {bad}"), &t, path.rsplit('.').next().unwrap());
        }
    }
    let set = |s: &str| toml::Value::Array(vec![toml::Value::String(s.into())]);
    let edits: Vec<(&str, &str, toml::Value)> = vec![
        ("preset unknown", "preset", toml::Value::String("no-such-method".into())),
        ("set of a wrong type", "batch_rays", set("batch_rays=x")),
        ("set of an unknown key", "no_such", set("no_such=1")),
        ("set without a name", "name", toml::Value::Integer(0)),
        ("scene missing", "scene", toml::Value::String("/nonexistent/scene.toml".into())),
    ];
    for (name, field, v) in edits {
        let mut t = base.clone();
        match name {
            "preset unknown" => set_method(&mut t, "preset", v),
            "set of a wrong type" | "set of an unknown key" => set_method(&mut t, "set", v),
            "set without a name" => {
                t["methods"].as_array_mut().unwrap()[0].as_table_mut().unwrap().remove("name");
            }
            _ => {
                t["scenes"].as_array_mut().unwrap()[0].as_table_mut().unwrap().insert("scene".into(), v);
            }
        }
        add(name.into(), &t, field);
    }
    for key in ["seeds", "methods", "scenes"] {
        let mut t = base.clone();
        t.insert(key.into(), toml::Value::Array(Vec::new()));
        add(format!("{key} empty"), &t, key);
        if key != "seeds" {
            // without seeds the matrix runs seed 0
            let mut t = base.clone();
            t.remove(key);
            add(format!("{key} removed"), &t, key);
        }
    }
    cases
}

fn set_method(t: &mut toml::Table, key: &str, v: toml::Value) {
    t["methods"].as_array_mut().unwrap()[0].as_table_mut().unwrap().insert(key.into(), v);
}

// ---------------------------------------------------------------------------------------------
// `evsim events`

fn events_cases() -> Vec<Case> {
    let frame =
        |i: u32| image::GrayImage::from_fn(16, 12, |x, y| image::Luma([((x * 13 + y * 7 + i * 29) % 256) as u8]));
    let setup = |name: &str, edit: &dyn Fn(&Path) -> Vec<String>| {
        let dir = case_dir("events", name);
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames).unwrap();
        for i in 0..6 {
            frame(i).save(frames.join(format!("{i:04}.png"))).unwrap();
        }
        std::fs::write(dir.join("timestamps.txt"), "0\n1000\n2000\n3000\n4000\n5000\n").unwrap();
        let extra = edit(&dir);
        let mut args = vec![OsString::from("events"), "--frames".into(), p(&frames)];
        args.extend(["--timestamps".into(), p(&dir.join("timestamps.txt")), "--timestamps-unit".into(), "us".into()]);
        if !extra.iter().any(|a| a == "--out") {
            args.extend(["--out".into(), p(&dir.join("events.h5"))]);
        }
        args.extend(extra.into_iter().map(OsString::from));
        args
    };
    run_ok(evsim(), &setup("base", &|_| Vec::new()));
    let mut cases = Vec::new();
    type Edit = Box<dyn Fn(&Path) -> Vec<String>>;
    let edits: Vec<(&str, &str, Edit)> = vec![
        (
            "a frame of another size",
            "0003.png",
            Box::new(|d| {
                image::GrayImage::new(8, 6).save(d.join("frames/0003.png")).unwrap();
                vec![]
            }),
        ),
        (
            "a 16-bit frame among 8-bit ones",
            "0003.png",
            Box::new(|d| {
                image::ImageBuffer::<image::Luma<u16>, _>::from_pixel(16, 12, image::Luma([300u16]))
                    .save(d.join("frames/0003.png"))
                    .unwrap();
                vec![]
            }),
        ),
        (
            "a truncated frame",
            "0003.png",
            Box::new(|d| {
                let b = std::fs::read(d.join("frames/0003.png")).unwrap();
                std::fs::write(d.join("frames/0003.png"), &b[..b.len() / 2]).unwrap();
                vec![]
            }),
        ),
        (
            "no frames",
            "frames",
            Box::new(|d| {
                std::fs::remove_dir_all(d.join("frames")).unwrap();
                std::fs::create_dir(d.join("frames")).unwrap();
                vec![]
            }),
        ),
        ("fewer timestamps", "timestamps.txt", Box::new(|d| write_times(d, "0\n1000\n2000\n"))),
        ("timestamp not a number", "timestamps.txt", Box::new(|d| write_times(d, "0\n1000\nabc\n3000\n4000\n5000\n"))),
        ("timestamps going back", "timestamps.txt", Box::new(|d| write_times(d, "0\n1000\n3000\n2000\n4000\n5000\n"))),
        ("timestamp NaN", "timestamps.txt", Box::new(|d| write_times(d, "0\n1000\nnan\n3000\n4000\n5000\n"))),
        ("threshold -1", "c_pos", Box::new(|_| vec!["--c-pos=-1".into()])),
        ("threshold NaN", "c_neg", Box::new(|_| vec!["--c-neg".into(), "nan".into()])),
        ("threshold 0", "c_pos", Box::new(|_| vec!["--c-pos".into(), "0".into()])),
        (
            "config with an unknown key",
            "config.toml",
            Box::new(|d| {
                std::fs::write(d.join("config.toml"), "no_such_setting = 1\n").unwrap();
                vec!["--config".into(), d.join("config.toml").to_string_lossy().into_owned()]
            }),
        ),
        (
            "output under a file",
            "blocker",
            Box::new(|d| {
                std::fs::write(d.join("blocker"), b"a file, not a folder").unwrap();
                vec!["--out".into(), d.join("blocker/events.h5").to_string_lossy().into_owned()]
            }),
        ),
    ];
    for (name, file, edit) in edits {
        let args = setup(name, edit.as_ref());
        cases.push(Case { family: "events", name: name.into(), exe: evsim(), args, must_name: vec![file.into()] });
    }
    cases
}

fn write_times(dir: &Path, text: &str) -> Vec<String> {
    std::fs::write(dir.join("timestamps.txt"), text).unwrap();
    Vec::new()
}

/// A family's case generator.
type Family = fn() -> Vec<Case>;

#[test]
fn every_bad_input_of_the_corpus_ends_in_a_clean_error() {
    let families: [(&str, Family); 8] = [
        ("gltf", gltf_cases),
        ("obj", obj_cases),
        ("scene-toml", scene_toml_cases),
        ("dataset", dataset_cases),
        ("checkpoint", checkpoint_cases),
        ("train-set", train_set_cases),
        ("matrix", matrix_cases),
        ("events", events_cases),
    ];
    let mut failures = Vec::new();
    let mut total = 0;
    for (family, make) in families {
        let cases = make();
        let results: Vec<(String, Outcome, String)> = cases
            .par_iter()
            .map(|c| {
                let start = std::time::Instant::now();
                let (o, text) = classify(c);
                let secs = start.elapsed().as_secs_f64();
                if secs > 5.0 {
                    println!("  slow case [{}] {}: {secs:.1} s", c.family, c.name);
                }
                (c.name.clone(), o, text)
            })
            .collect();
        let count = |f: &dyn Fn(&Outcome) -> bool| results.iter().filter(|r| f(&r.1)).count();
        println!(
            "{family:<11} {:>4} cases: {:>4} clean, {} panics, {} aborts, {} silent successes, {} unclear messages",
            results.len(),
            count(&|o| *o == Outcome::Clean),
            count(&|o| *o == Outcome::Panic),
            count(&|o| matches!(o, Outcome::Abort(_))),
            count(&|o| *o == Outcome::SilentSuccess),
            count(&|o| matches!(o, Outcome::Unclear(_))),
        );
        total += results.len();
        for (name, outcome, text) in results {
            if outcome != Outcome::Clean {
                let tail: String =
                    text.lines().rev().take(6).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n    ");
                let line = format!("[{family}] {name}: {outcome:?}\n    {tail}");
                println!("{line}");
                failures.push(line);
            }
        }
    }
    println!("bad-input corpus: {total} cases, {} not clean", failures.len());
    assert!(total >= 300, "the corpus shrank to {total} cases");
    assert!(
        failures.is_empty(),
        "{} of {total} bad inputs did not end in a clean error:\n{}",
        failures.len(),
        failures.join("\n")
    );
    let _ = std::fs::remove_dir_all(root());
}
