//! Matrix files: a valid one resolves into sorted, keyed cells; every mistake is an error that
//! names the file, the field and the fix.

use std::path::{Path, PathBuf};

use super::*;

/// The repository's `scenes/tiny/scene.toml`.
fn tiny() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml")
}

/// A folder for this test's matrix files.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("evbench-plan-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` as `matrix.toml` in `d` and resolves it.
fn load(d: &Path, text: &str) -> Result<MatrixPlan, BenchError> {
    let file = d.join("matrix.toml");
    std::fs::write(&file, text).unwrap();
    MatrixPlan::load(&file, None)
}

/// The error message of resolving `text`.
fn error(d: &Path, text: &str) -> String {
    load(d, text).unwrap_err().to_string()
}

#[test]
fn a_matrix_resolves_into_keyed_cells() {
    let d = dir("ok");
    let text = format!(
        r#"
scale = "cpu"
iterations = 20
seeds = [0, 3]
set = ["eval_every=0"]
[dataset]
width = 32
height = 24
[[methods]]
preset = "nerf"
[[methods]]
preset = "ev-deblurnerf"
name = "no-edi"
set = ["edi=none"]
[[scenes]]
scene = "{}"
[[scenes]]
name = "tiny-sharp-spp"
scene = "{}"
dataset = {{ sharp_spp = 8, height = 32 }}
"#,
        tiny().display(),
        tiny().parent().unwrap().display()
    );
    let plan = load(&d, &text).unwrap();
    assert_eq!(plan.results, PathBuf::from(DEFAULT_RESULTS));
    assert_eq!(plan.cells.len(), 2 * 2 * 2);
    assert!(plan.cells.windows(2).all(|w| w[0].key < w[1].key), "sorted by key");
    let names: Vec<&str> = plan.scenes.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["tiny", "tiny-sharp-spp"]);
    // The scene's overrides go over the matrix's, key by key.
    let SceneSource::Simulate(p) = &plan.scenes[1].source else { panic!("simulated") };
    assert_eq!((p.config.width, p.config.height, p.sharp_spp), (32, 32, Some(8)));
    assert_ne!(plan.scenes[0].identity, plan.scenes[1].identity);
    let m = &plan.methods[1];
    assert_eq!((m.name.as_str(), m.preset.name), ("no-edi", "ev-deblurnerf"));
    assert_eq!(m.set, ["eval_every=0", "edi=none"]);
    assert_eq!(m.switches, ["edi=none"]);
    assert!(m.config.edi.is_none() && m.config.iterations == 20 && m.config.eval_every == 0);
    let c = plan.cells.iter().find(|c| c.method == 1 && c.scene == 0 && c.seed == 3).unwrap();
    assert_eq!(c.config.seed, 3);
    assert_eq!(plan.cell_dir(c), Path::new(DEFAULT_RESULTS).join("tiny/no-edi").join(&c.key));
    let data = plan.scenes[0].dataset_dir(&plan.results);
    assert_eq!(data, Path::new(DEFAULT_RESULTS).join("datasets").join(&plan.scenes[0].identity[..16]));
    // The same file gives the same keys; --results moves the folder only.
    let again = MatrixPlan::load(&d.join("matrix.toml"), Some(Path::new("/r"))).unwrap();
    assert_eq!(again.results, Path::new("/r"));
    let keys = |p: &MatrixPlan| p.cells.iter().map(|c| c.key.clone()).collect::<Vec<_>>();
    assert_eq!(keys(&plan), keys(&again));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn mistakes_name_the_file_the_field_and_the_fix() {
    let d = dir("errors");
    let scene = format!("[[scenes]]\nscene = \"{}\"\n", tiny().display());
    let nerf = "[[methods]]\npreset = \"nerf\"\n";
    let cases: Vec<(String, &[&str])> = vec![
        (format!("scale = \"cpu\"\nmethodz = 1\n{nerf}{scene}"), &["line 2", "unknown field `methodz`", "config.rs"]),
        (format!("scale = \"gpu\"\n{nerf}{scene}"), &["line 1", "unknown variant `gpu`"]),
        (format!("{nerf}{scene}"), &["missing field `scale`"]),
        (format!("scale = \"cpu\"\n[[methods]]\npreset = \"nerf\"\nsett = []\n{scene}"), &["line 4", "unknown field `sett`"]),
        (format!("scale = \"cpu\"\n[[methods]]\npreset = \"nerff\"\n{scene}"), &["methods[0].preset", "`nerff` is not a preset", "ev-deblurnerf"]),
        (format!("scale = \"cpu\"\n{nerf}[[methods]]\npreset = \"nerf\"\nset = [\"edi=none\"]\n{scene}"), &["methods[1].name", "needs a name"]),
        (format!("scale = \"cpu\"\n{nerf}[[methods]]\npreset = \"nerf-sharp\"\nname = \"nerf\"\n{scene}"), &["methods[1].name", "also methods[0]'s name"]),
        (format!("scale = \"cpu\"\n[[methods]]\npreset = \"nerf\"\nname = \"a b\"\n{scene}"), &["methods[0].name", "`a b`", "letters, digits"]),
        (format!("scale = \"cpu\"\n[[methods]]\npreset = \"nerf\"\nname = \"x\"\nset = [\"events.colur=true\"]\n{scene}"), &["methods[0].set", "`events` is not in this configuration", "preset nerf"]),
        (format!("scale = \"cpu\"\n[[methods]]\npreset = \"nerf\"\nname = \"x\"\nset = [\"iterations=0\"]\n{scene}"), &["methods[0].set", "iterations"]),
        (format!("scale = \"cpu\"\n{nerf}[[methods]]\npreset = \"nerf\"\nname = \"nerf2\"\nset = [\"iterations=8000\"]\n{scene}"), &["methods[1]", "same configuration as methods[0]"]),
        (format!("scale = \"cpu\"\nseeds = []\n{nerf}{scene}"), &["seeds", "at least one"]),
        (format!("scale = \"cpu\"\nseeds = [1, 2, 1]\n{nerf}{scene}"), &["seeds", "1 appears twice"]),
        (format!("scale = \"cpu\"\niterations = 0\n{nerf}{scene}"), &["iterations", "positive"]),
        (format!("scale = \"cpu\"\nmethods = []\n{scene}"), &["methods", "is empty"]),
        (format!("scale = \"cpu\"\nscenes = []\n{nerf}"), &["scenes", "is empty"]),
        (format!("scale = \"cpu\"\n{nerf}[[scenes]]\nname = \"x\"\n"), &["scenes[0]", "exactly one of `scene`"]),
        (format!("scale = \"cpu\"\n{nerf}[[scenes]]\nscene = \"nowhere/scene.toml\"\n"), &["scenes[0].scene", "does not exist", "relative to this file"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}{scene}"), &["scenes[1].name", "`tiny` is also scenes[0]'s name"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}name = \"datasets\"\n"), &["scenes[0].name", "reserved"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}dataset = {{ width = 0 }}\n"), &["scenes[0].scene", "dataset.width/height", "1..=16384"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}dataset = {{ widht = 3 }}\n"), &["scenes[0].dataset.widht", "unknown field `widht`", "DatasetConfig", "docs/simulator.md"]),
        (format!("scale = \"cpu\"\n[dataset]\nspp = \"many\"\n{nerf}{scene}"), &["dataset.spp", "invalid type"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}dataset = {{ speed = 0 }}\n"), &["scenes[0].dataset.speed", "positive factor"]),
        (format!("scale = \"cpu\"\n{nerf}{scene}dataset = {{ set = [\"dataset.widht=3\"] }}\n"), &["scenes[0].scene", "widht"]),
        (format!("scale = \"cpu\"\n{nerf}[[scenes]]\ndata = \".\"\ndataset = {{ spp = 2 }}\n"), &["scenes[0].dataset", "used as it is"]),
    ];
    for (text, says) in cases {
        let e = error(&d, &text);
        assert!(e.starts_with(&format!("{}: ", d.join("matrix.toml").display())), "{text}\n-> {e}");
        for s in says {
            assert!(e.contains(s), "{text}\n-> {e}\nlacks {s:?}");
        }
    }
    let e = MatrixPlan::load(&d.join("absent.toml"), None).unwrap_err().to_string();
    assert!(e.contains("absent.toml: file: cannot read"), "{e}");
    // a mistake in the matrix's own `set` is reported there, not in the first method's
    let e = error(&d, &format!("scale = \"cpu\"\nset = [\"events.colur=true\"]\n{nerf}{scene}"));
    assert!(e.contains("matrix.toml: set: ") && !e.contains("methods[0].set"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_more_specific_iterations_win() {
    let d = dir("iterations");
    let text = format!(
        "scale = \"cpu\"\niterations = 20\n[[methods]]\npreset = \"nerf\"\n[[methods]]\npreset = \"e-nerf\"\nname = \"long\"\nset = [\"iterations=50\"]\n[[scenes]]\nscene = \"{}\"\n",
        tiny().display()
    );
    let plan = load(&d, &text).unwrap();
    let its: Vec<u64> = plan.methods.iter().map(|m| m.config.iterations).collect();
    assert_eq!(its, [20, 50], "the matrix's iterations, then a method's own set");
    let top = text.replace("iterations = 20\n", "iterations = 20\nset = [\"iterations=30\"]\n");
    let its: Vec<u64> = load(&d, &top).unwrap().methods.iter().map(|m| m.config.iterations).collect();
    assert_eq!(its, [30, 50]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_dataset_folder_is_named_after_itself_and_keyed_by_its_content() {
    let d = dir("folder");
    let data = d.join("blurfactory");
    std::fs::create_dir_all(&data).unwrap();
    std::fs::write(data.join("poses_bounds.npy"), b"1").unwrap();
    let text = "scale = \"paper\"\n[[methods]]\npreset = \"nerf\"\n[[scenes]]\ndata = \"blurfactory\"\n";
    let plan = load(&d, text).unwrap();
    assert_eq!(plan.scenes[0].name, "blurfactory");
    assert_eq!(plan.scenes[0].dataset_dir(&plan.results), data);
    let key = plan.cells[0].key.clone();
    std::fs::write(data.join("poses_bounds.npy"), b"2").unwrap();
    assert_ne!(load(&d, text).unwrap().cells[0].key, key);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_shipped_table_configs_list_every_preset_in_registry_order() {
    let registry: Vec<&str> = trainer::presets::PRESETS.iter().map(|p| p.name).collect();
    for name in ["table1.toml", "paper.toml"] {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs").join(name);
        let text = std::fs::read_to_string(&file).unwrap();
        let cfg: crate::matrix::config::MatrixConfig = toml::from_str(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let listed: Vec<&str> = cfg.methods.iter().map(|m| m.preset.as_str()).collect();
        assert_eq!(listed, registry, "{name} must list every preset of the registry");
    }
}
