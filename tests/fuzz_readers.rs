//! A mutation fuzz run over the readers of files other tools write: glTF (`.gltf` + `.bin`, and
//! `.glb`), the event `.h5` (the trainer's reader, chunked+deflated and contiguous files), NumPy
//! `.npy` / `.npz` (stored and deflated members) and checkpoints. Each iteration takes a valid
//! file, applies one to three random mutations (bit flips, byte overwrites, deletions,
//! insertions, truncation, 4- and 8-byte integers at random offsets, and in JSON text numbers
//! replaced by boundary values) and reads it. A reader must either return an error or return
//! data that keeps its documented promises (finite geometry and indices in range; events inside
//! the image, inside the time range, in time order, of polarity +-1; arrays as long as their
//! shape; for checkpoints, which carry a checksum, no changed file loads at all). Panics are
//! caught and counted; the test fails on any panic or broken promise.
//!
//! `EVBLUR_FUZZ_ITERS` (default 2000) sets the iterations per reader; the seed is fixed, so a
//! failure repeats. The long run quoted in `benchmark/results/` used 50000.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use evblur_tests::temp_dir;
use simulator::dataset::check::EventsUnit;
use simulator::events::sinks::NerfH5Sink;
use simulator::events::{Event, EventSink};
use simulator::npy::{read_npy, read_npz, write_npy, write_npz, NpyArray};
use simulator::scene::{PunctualLight, Scene};
use trainer::checkpoint::Checkpoint;
use trainer::data::events::Events;
use trainer::engine::adam::Adam;
use trainer::engine::params::{Layout, LrClass};

/// SplitMix64: a small seeded generator (the run must repeat).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const INTERESTING_BYTES: &[u8] = &[0, 1, 0x7f, 0x80, 0xff, b'"', b'-', b'9', b'[', b'{', b'}', b','];
const INTERESTING_INTS: &[u64] =
    &[0, 1, 2, 7, 8, 255, 256, 65535, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 1 << 40, u64::MAX, i64::MAX as u64];
const INTERESTING_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "3",
    "99",
    "65535",
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "1e308",
    "-1e308",
    "1e-320",
    "0.5",
    "-0.0",
    "2.5e9",
];

/// Applies one to three random mutations to `bytes`; `text` adds number replacements.
fn mutate(rng: &mut Rng, bytes: &[u8], text: bool) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for _ in 0..1 + rng.below(3) {
        let len = b.len();
        match rng.below(if text { 9 } else { 8 }) {
            0 if len > 0 => {
                let i = rng.below(len);
                b[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                b[i] = rng.next() as u8;
            }
            2 if len > 0 => {
                let i = rng.below(len);
                b[i] = INTERESTING_BYTES[rng.below(INTERESTING_BYTES.len())];
            }
            3 if len > 0 => {
                let i = rng.below(len);
                let n = (1 + rng.below(16)).min(len - i);
                b.drain(i..i + n);
            }
            4 => {
                let i = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let insert: Vec<u8> = if len > 0 && rng.below(2) == 0 {
                    let from = rng.below(len);
                    b[from..(from + n).min(len)].to_vec()
                } else {
                    (0..n).map(|_| rng.next() as u8).collect()
                };
                b.splice(i..i, insert);
            }
            5 if len > 0 => {
                b.truncate(rng.below(len));
            }
            6 | 7 if len >= 8 => {
                let v = INTERESTING_INTS[rng.below(INTERESTING_INTS.len())];
                let width = if rng.below(2) == 0 { 4 } else { 8 };
                let i = rng.below(len - width + 1);
                b[i..i + width].copy_from_slice(&v.to_le_bytes()[..width]);
            }
            8 => {
                // Replace a run of digits with a boundary number.
                let starts: Vec<usize> =
                    (0..len).filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit())).collect();
                if let Some(&s) = starts.get(rng.below(starts.len())) {
                    let e = (s..len).find(|&i| !(b[i].is_ascii_digit() || b[i] == b'.')).unwrap_or(len);
                    let num = INTERESTING_NUMBERS[rng.below(INTERESTING_NUMBERS.len())];
                    b.splice(s..e, num.bytes());
                }
            }
            _ => {}
        }
    }
    b
}

/// Where and why the last caught panic happened (set by the test's panic hook).
static LAST_PANIC: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// The tally of one reader's run.
#[derive(Default)]
struct Tally {
    errors: usize,
    accepted: usize,
    panics: Vec<String>,
    broken: Vec<String>,
}

impl Tally {
    fn record(&mut self, iteration: usize, result: std::thread::Result<Result<Option<String>, String>>) {
        match result {
            Err(_) => {
                let at = std::mem::take(&mut *LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()));
                self.panics.push(format!("iteration {iteration}: {at}"));
            }
            Ok(Err(_)) => self.errors += 1,
            Ok(Ok(None)) => self.accepted += 1,
            Ok(Ok(Some(problem))) => self.broken.push(format!("iteration {iteration}: {problem}")),
        }
    }
}

fn iterations() -> usize {
    std::env::var("EVBLUR_FUZZ_ITERS").ok().and_then(|v| v.parse().ok()).unwrap_or(2000)
}

/// Runs `iterations()` mutants of `files` (name, bytes, is text) through `read`, which sees the
/// folder the mutants were written to and returns Err (refused), Ok(None) (accepted, promises
/// kept) or Ok(Some(problem)).
fn fuzz(
    name: &str,
    seed: u64,
    files: &[(&str, Vec<u8>, bool)],
    read: &dyn Fn(&Path) -> Result<Option<String>, String>,
) -> Tally {
    let dir = temp_dir("fuzz", name);
    let mut rng = Rng(seed);
    let mut tally = Tally::default();
    for it in 0..iterations() {
        // Mutate one of the files (the others stay valid).
        let k = rng.below(files.len());
        for (j, (file, bytes, text)) in files.iter().enumerate() {
            let out = if j == k { mutate(&mut rng, bytes, *text) } else { bytes.clone() };
            std::fs::write(dir.join(file), out).unwrap();
        }
        tally.record(it, catch_unwind(AssertUnwindSafe(|| read(&dir))));
    }
    tally
}

// ---------------------------------------------------------------------------------------------
// glTF

/// A textured quad, a camera and a point light (as the bad-input corpus's base scene).
fn gltf_files() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    let mut bin = Vec::new();
    for v in [-1.0f32, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0] {
        bin.extend(v.to_le_bytes());
    }
    for v in [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0] {
        bin.extend(v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1,2]}],
"nodes":[{"mesh":0,"rotation":[0,0,0,1],"scale":[1,1,1]},{"camera":0,"translation":[0,0,3]},
{"translation":[0,0,2],"extensions":{"KHR_lights_punctual":{"light":0}}}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},"indices":3,"material":0}]}],
"materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0},"baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":1},"emissiveFactor":[0,0,0]}],
"textures":[{"source":0,"sampler":0}],"samplers":[{"magFilter":9729,"minFilter":9729,"wrapS":10497,"wrapT":10497}],
"images":[{"uri":"tex.png"}],
"cameras":[{"type":"perspective","perspective":{"yfov":0.8,"znear":0.1,"zfar":100,"aspectRatio":1}}],
"extensionsUsed":["KHR_lights_punctual"],
"extensions":{"KHR_lights_punctual":{"lights":[{"type":"spot","color":[1,1,1],"intensity":50,"spot":{"innerConeAngle":0.2,"outerConeAngle":0.6}}]}},
"buffers":[{"uri":"scene.bin","byteLength":140}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":48},{"buffer":0,"byteOffset":96,"byteLength":32},{"buffer":0,"byteOffset":128,"byteLength":12}],
"accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]},
{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"},{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"},
{"bufferView":3,"componentType":5123,"count":6,"type":"SCALAR"}]}"#;
    let img = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 128]));
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png).unwrap();
    (json.as_bytes().to_vec(), bin, png.into_inner())
}

/// The `.glb` form of the same scene.
fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let text = String::from_utf8(json.to_vec()).unwrap().replace(r#""uri":"scene.bin","#, "");
    let mut js = text.into_bytes();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + js.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// The promises of a loaded scene: finite geometry, indices in range, sane lights and cameras.
fn scene_problem(s: &Scene) -> Option<String> {
    let m = &s.mesh;
    let n = m.positions.len();
    if m.normals.len() != n || m.uvs.len() != n {
        return Some(format!("{n} positions, {} normals, {} uvs", m.normals.len(), m.uvs.len()));
    }
    if let Some(p) = m.positions.iter().find(|p| !p.is_finite()) {
        return Some(format!("position {p}"));
    }
    if let Some(v) = m.normals.iter().find(|v| !v.is_finite()) {
        return Some(format!("normal {v}"));
    }
    if let Some(v) = m.uvs.iter().find(|v| !v.is_finite()) {
        return Some(format!("uv {v}"));
    }
    if let Some(t) = m.indices.iter().find(|t| t.iter().any(|&i| i as usize >= n)) {
        return Some(format!("triangle {t:?} of {n} vertices"));
    }
    for mat in &s.materials {
        let factors = [mat.metallic, mat.roughness, mat.specular];
        if !mat.base_color.is_finite()
            || !mat.emission.is_finite()
            || mat.base_color.min_element() < 0.0
            || mat.emission.min_element() < 0.0
            || factors.iter().any(|f| !(0.0..=1.0).contains(f))
        {
            return Some(format!("material {mat:?}"));
        }
        for t in [&mat.base_color_texture, &mat.metallic_roughness_texture, &mat.emission_texture].into_iter().flatten()
        {
            if t.index as usize >= s.textures.len() {
                return Some(format!("texture {} of {}", t.index, s.textures.len()));
            }
        }
    }
    for l in &s.lights {
        let ok = match l {
            PunctualLight::Point { position, intensity } => {
                position.is_finite() && intensity.is_finite() && intensity.min_element() >= 0.0
            }
            PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
                position.is_finite()
                    && direction.is_finite()
                    && intensity.is_finite()
                    && intensity.min_element() >= 0.0
                    && (0.0..=*outer_cone).contains(inner_cone)
                    && *outer_cone <= std::f32::consts::FRAC_PI_2
            }
            PunctualLight::Directional { direction, irradiance } => {
                direction.is_finite() && irradiance.is_finite() && irradiance.min_element() >= 0.0
            }
        };
        if !ok {
            return Some(format!("light {l:?}"));
        }
    }
    for c in &s.cameras {
        if !(c.yfov > 0.0 && c.yfov < std::f32::consts::PI && c.to_world.is_finite()) {
            return Some(format!("camera {c:?}"));
        }
    }
    None
}

fn load_scene(path: &Path) -> Result<Option<String>, String> {
    simulator::scene::load(path).map(|s| scene_problem(&s)).map_err(|e| e.to_string())
}

// ---------------------------------------------------------------------------------------------
// Events

const W: u32 = 16;
const H: u32 = 12;
const RANGE_US: (f64, f64) = (0.0, 1.0e6);

fn events_files(dir: &Path) -> Vec<u8> {
    let events: Vec<Event> = (0..3000u32)
        .map(|i| Event {
            x: (i * 7 % W) as u16,
            y: (i * 5 % H) as u16,
            t_ns: 1000 + 300_000 * i as i64,
            p: if i % 3 == 0 { 1 } else { -1 },
        })
        .collect();
    let path = dir.join("events.h5");
    let mut sink = NerfH5Sink::create(&path).unwrap();
    sink.push(&events).unwrap();
    sink.finish().unwrap();
    std::fs::read(&path).unwrap()
}

/// Contiguous, uncompressed columns, as h5py writes by default.
fn events_plain(dir: &Path) -> Vec<u8> {
    let path = dir.join("plain.h5");
    let file = rust_hdf5::H5File::create(&path).unwrap();
    let n = 500usize;
    let x: Vec<u16> = (0..n).map(|i| (i * 3 % W as usize) as u16).collect();
    let y: Vec<u16> = (0..n).map(|i| (i * 5 % H as usize) as u16).collect();
    let t: Vec<i64> = (0..n).map(|i| 5000 + 1_000_000 * i as i64).collect();
    let p: Vec<u8> = (0..n).map(|i| (i % 2) as u8).collect();
    file.new_dataset::<u16>().shape([n]).create("x").unwrap().write_raw(&x).unwrap();
    file.new_dataset::<u16>().shape([n]).create("y").unwrap().write_raw(&y).unwrap();
    file.new_dataset::<i64>().shape([n]).create("t").unwrap().write_raw(&t).unwrap();
    file.new_dataset::<u8>().shape([n]).create("p").unwrap().write_raw(&p).unwrap();
    file.close().unwrap();
    std::fs::read(&path).unwrap()
}

/// The promises of [`Events::read`]'s result.
fn events_problem(ev: &Events) -> Option<String> {
    let n = ev.len();
    if [ev.x.len(), ev.y.len(), ev.polarity.len(), ev.successors.len()].iter().any(|&l| l != n) {
        return Some("columns of different lengths".into());
    }
    for i in 0..n {
        let (x, y, t) = (ev.x[i], ev.y[i], ev.t_us[i]);
        let inside = x >= 0.0 && y >= 0.0 && x < W as f32 && y < H as f32 && x.fract() == 0.0;
        if !ev.float_coordinates && !inside {
            return Some(format!("event {i} at ({x}, {y})"));
        }
        if !(t >= RANGE_US.0 && t <= RANGE_US.1) {
            return Some(format!("event {i} at t = {t} us"));
        }
        if i > 0 && t < ev.t_us[i - 1] {
            return Some(format!("event {i} at t = {t} us after {}", ev.t_us[i - 1]));
        }
        if ev.polarity[i] != 1 && ev.polarity[i] != -1 {
            return Some(format!("event {i} of polarity {}", ev.polarity[i]));
        }
        if let Some(s) = ev.successor(i) {
            if s <= i || s >= n || ev.x[s] != x || ev.y[s] != y {
                return Some(format!("event {i} has successor {s}"));
            }
        }
    }
    None
}

fn read_events(dir: &Path) -> Result<Option<String>, String> {
    Events::read(dir, EventsUnit::Ns, RANGE_US, (W, H), 256).map(|e| events_problem(&e)).map_err(|e| e.to_string())
}

// ---------------------------------------------------------------------------------------------
// NumPy

fn array_problem(name: &str, a: &NpyArray) -> Option<String> {
    let want: usize = a.shape().iter().product();
    let have = a.data().to_f64().len();
    (want != have).then(|| format!("{name}: shape {:?} with {have} values", a.shape()))
}

/// A deflated `.npz` (as numpy.savez_compressed writes) of one f64 array: a zip built by hand.
fn npz_deflated(array: &NpyArray) -> Vec<u8> {
    use std::io::Write;
    let raw = array.to_npy_bytes();
    let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::default());
    enc.write_all(&raw).unwrap();
    let data = enc.finish().unwrap();
    let crc = {
        let mut c = flate2::Crc::new();
        c.update(&raw);
        c.sum()
    };
    let name = b"timestamps.npy";
    let mut out = Vec::new();
    let header = |out: &mut Vec<u8>, central: bool| {
        out.extend(if central { 0x0201_4b50u32 } else { 0x0403_4b50u32 }.to_le_bytes());
        if central {
            out.extend(20u16.to_le_bytes());
        }
        out.extend(20u16.to_le_bytes()); // version needed
        out.extend(0u16.to_le_bytes()); // flags
        out.extend(8u16.to_le_bytes()); // deflate
        out.extend([0u8; 4]); // time, date
        out.extend(crc.to_le_bytes());
        out.extend((data.len() as u32).to_le_bytes());
        out.extend((raw.len() as u32).to_le_bytes());
        out.extend((name.len() as u16).to_le_bytes());
        out.extend(0u16.to_le_bytes()); // extra
        if central {
            out.extend([0u8; 8]); // comment length, disk, internal attributes
            out.extend([0u8; 4]); // external attributes
            out.extend(0u32.to_le_bytes()); // local header offset
        }
        out.extend(name);
    };
    header(&mut out, false);
    out.extend(&data);
    let central_at = out.len();
    header(&mut out, true);
    let central_len = out.len() - central_at;
    out.extend(0x0605_4b50u32.to_le_bytes());
    out.extend([0u8; 4]);
    out.extend(1u16.to_le_bytes());
    out.extend(1u16.to_le_bytes());
    out.extend((central_len as u32).to_le_bytes());
    out.extend((central_at as u32).to_le_bytes());
    out.extend(0u16.to_le_bytes());
    out
}

// ---------------------------------------------------------------------------------------------
// Checkpoints

fn checkpoint_layout() -> Layout {
    let mut layout = Layout::default();
    layout.alloc("volume", 300, LrClass::Volume);
    layout.alloc("mlp", 77, LrClass::Network);
    layout
}

fn print(name: &str, t: &Tally) -> Vec<String> {
    println!(
        "{name:<16} {:>6} mutants: {:>6} refused, {:>6} accepted (promises kept), {} panics, {} broken promises",
        t.errors + t.accepted + t.panics.len() + t.broken.len(),
        t.errors,
        t.accepted,
        t.panics.len(),
        t.broken.len()
    );
    t.panics
        .iter()
        .map(|p| format!("{name}: panic at {p}"))
        .chain(t.broken.iter().map(|b| format!("{name}: {b}")))
        .collect()
}

#[test]
fn mutated_files_are_refused_or_read_within_their_promises_never_a_panic() {
    // Readers' panics are caught and counted; keep their messages off the output.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|info| {
        let at = info.location().map(|l| format!("{}:{}", l.file(), l.line())).unwrap_or_default();
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        *LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()) = format!("{at}: {msg}");
    }));
    let mut failures = Vec::new();

    let (json, bin, png) = gltf_files();
    let base = temp_dir("fuzz", "base");
    for (f, b) in [("scene.gltf", &json), ("scene.bin", &bin), ("tex.png", &png)] {
        std::fs::write(base.join(f), b).unwrap();
    }
    assert_eq!(load_scene(&base.join("scene.gltf")), Ok(None), "the base glTF");
    let files =
        [("scene.gltf", json.clone(), true), ("scene.bin", bin.clone(), false), ("tex.png", png.clone(), false)];
    let t = fuzz("gltf", 1, &files, &|d| load_scene(&d.join("scene.gltf")));
    failures.extend(print("gltf", &t));

    let glb_bytes = glb(&json, &bin);
    std::fs::write(base.join("scene.glb"), &glb_bytes).unwrap();
    assert_eq!(load_scene(&base.join("scene.glb")), Ok(None), "the base glb");
    let files = [("scene.glb", glb_bytes, false), ("tex.png", png, false)];
    let t = fuzz("glb", 2, &files, &|d| load_scene(&d.join("scene.glb")));
    failures.extend(print("glb", &t));

    for (name, bytes, seed) in [("h5 chunked", events_files(&base), 3), ("h5 contiguous", events_plain(&base), 4)] {
        std::fs::write(base.join("events.h5"), &bytes).unwrap();
        assert_eq!(read_events(&base), Ok(None), "the base {name} events");
        let t = fuzz(&name.replace(' ', "-"), seed, &[("events.h5", bytes, false)], &read_events);
        failures.extend(print(name, &t));
    }

    let array = NpyArray::f64_2d(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.5]]);
    write_npy(&base.join("a.npy"), &array).unwrap();
    let npy = std::fs::read(base.join("a.npy")).unwrap();
    let read_one = |d: &Path| read_npy(&d.join("a.npy")).map(|a| array_problem("a", &a)).map_err(|e| e.to_string());
    let t = fuzz("npy", 5, &[("a.npy", npy, false)], &read_one);
    failures.extend(print("npy", &t));
    let t_mid = NpyArray::vector((0..20).map(|i| 1000.0 * i as f64).collect::<Vec<f64>>());
    write_npz(&base.join("t.npz"), &[("timestamps", t_mid.clone()), ("poses", array)]).unwrap();
    let read_all = |d: &Path| -> Result<Option<String>, String> {
        let arrays = read_npz(&d.join("t.npz")).map_err(|e| e.to_string())?;
        Ok(arrays.iter().find_map(|(k, a)| array_problem(k, a)))
    };
    let stored = std::fs::read(base.join("t.npz")).unwrap();
    let t = fuzz("npz-stored", 6, &[("t.npz", stored, false)], &read_all);
    failures.extend(print("npz stored", &t));
    let deflated = npz_deflated(&t_mid);
    std::fs::write(base.join("t.npz"), &deflated).unwrap();
    assert_eq!(read_all(&base), Ok(None), "the base deflated npz");
    let t = fuzz("npz-deflated", 7, &[("t.npz", deflated, false)], &read_all);
    failures.extend(print("npz deflated", &t));

    let layout = checkpoint_layout();
    let n = layout.len();
    let ck = Checkpoint {
        step: 123,
        seconds: 0.0,
        params: (0..n).map(|i| (i as f32 * 0.37).sin()).collect(),
        adam: Adam { m: (0..n).map(|i| i as f32 * 1e-3).collect(), v: vec![1e-4; n], t: 123 },
        occupancy: Some(vec![0xdead_beef_0123_4567, u64::MAX, 0]),
    };
    let ck_path = base.join("checkpoint.bin");
    ck.save(&layout, &ck_path).unwrap();
    let original = std::fs::read(&ck_path).unwrap();
    assert_eq!(Checkpoint::load(&layout, &ck_path).unwrap(), ck);
    let read_ck = |d: &Path| -> Result<Option<String>, String> {
        let path = d.join("checkpoint.bin");
        let changed = std::fs::read(&path).unwrap() != original;
        match Checkpoint::load(&layout, &path) {
            Err(e) => Ok(Err(e.to_string())),
            Ok(_) if changed => Ok(Ok(Some("a changed checkpoint loaded".to_string()))),
            Ok(_) => Ok(Ok(None)),
        }
        .and_then(|r| r)
    };
    let t = fuzz("checkpoint", 8, &[("checkpoint.bin", original.clone(), false)], &read_ck);
    failures.extend(print("checkpoint", &t));

    std::panic::set_hook(hook);
    assert!(failures.is_empty(), "{} readers' failures:\n{}", failures.len(), failures.join("\n"));
    for name in
        ["base", "gltf", "glb", "h5-chunked", "h5-contiguous", "npy", "npz-stored", "npz-deflated", "checkpoint"]
    {
        let _ = std::fs::remove_dir_all(temp_dir("fuzz", name));
    }
}
