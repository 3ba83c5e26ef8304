//! The dataset and run families of the corpus: datasets, checkpoints and run folders,
//! `evtrain --set`, run matrices and `evsim events`.

use super::*;

// ---------------------------------------------------------------------------------------------
// Datasets (through `evsim check` and `evtrain train`)

/// A small dataset of `scenes/tiny` (32x24, 1 spp), simulated once.
pub(super) fn base_dataset() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = case_dir("dataset", "base");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml");
        let mut args = vec![OsString::from("dataset"), p(&scene), "--out".into(), p(&dir)];
        args.extend(os(&["--set", "dataset.width=32", "--set", "dataset.height=24", "--set", "dataset.spp=1"]));
        args.extend(os(&["--set", "dataset.sharp_spp=1", "--set", "dataset.shading=path_traced", "--quiet"]));
        run_ok(evsim(), &args);
        dir
    })
}

/// Small-model `evtrain train` flags: seconds per run.
pub(super) const SMALL: &[&str] =
    &["--set", "model.coarse_volume.res=16", "--iterations", "1", "--quiet", "--threads", "1"];

pub(super) fn train_args(data: &Path, preset: &str, out: &Path) -> Vec<OsString> {
    let mut a = vec![OsString::from("train"), "--data".into(), p(data), "--preset".into(), preset.into()];
    a.extend(["--out".into(), p(out)]);
    a.extend(os(SMALL));
    a
}

pub(super) fn write_h5(path: &Path, columns: &[(&str, H5Column)]) {
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

pub(super) enum H5Column {
    I64(Vec<i64>),
    F64(Vec<f64>),
}

/// The base dataset's events as columns (x, y, t, p).
pub(super) fn base_events() -> [Vec<i64>; 4] {
    let file = rust_hdf5::H5File::open(base_dataset().join("events.h5")).unwrap();
    let col = |name: &str| -> Vec<i64> {
        let reader = simulator::dataset::EventColumnReader::open(&file, name).unwrap();
        let chunk = reader.read(0, reader.len()).unwrap();
        (0..reader.len()).map(|i| chunk.get(i) as i64).collect()
    };
    [col("x"), col("y"), col("t"), col("p")]
}

pub(super) fn dataset_cases() -> Vec<Case> {
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

pub(super) fn checkpoint_cases() -> Vec<Case> {
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

pub(super) fn train_set_cases() -> Vec<Case> {
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

pub(super) fn matrix_cases() -> Vec<Case> {
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

pub(super) fn set_method(t: &mut toml::Table, key: &str, v: toml::Value) {
    t["methods"].as_array_mut().unwrap()[0].as_table_mut().unwrap().insert(key.into(), v);
}

// ---------------------------------------------------------------------------------------------
// `evsim events`

pub(super) fn events_cases() -> Vec<Case> {
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

pub(super) fn write_times(dir: &Path, text: &str) -> Vec<String> {
    std::fs::write(dir.join("timestamps.txt"), text).unwrap();
    Vec::new()
}

/// A family's case generator.
pub(super) type Family = fn() -> Vec<Case>;
