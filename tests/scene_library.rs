//! Every dataset scene in `scenes/` (each folder whose `scene.toml` has a `[trajectory]`)
//! loads and goes through `evsim dataset` at a thumbnail size into a folder that passes the
//! schema check: the committed scenes stay usable.

use std::path::Path;

use evblur_tests::temp_dir;
use simulator::dataset::check::{check_dataset, CheckOptions, EventsUnit, TestViewPolicy};
use simulator::dataset::{write_dataset, Overrides, Plan, RunOptions, Shading};

#[test]
fn every_dataset_scene_makes_a_dataset_that_passes_the_check() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut names: Vec<String> = std::fs::read_dir(&scenes)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| std::fs::read_to_string(p.join("scene.toml")).is_ok_and(|t| t.contains("[trajectory]")))
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for must in ["cbox", "tiny"] {
        assert!(names.iter().any(|n| n == must), "scenes/{must} is missing from {names:?}");
    }
    let dir = temp_dir("scenes", "datasets");
    // thumbnails: 1 spp, 48x32 (the frame count, views and timing stay the scene's own)
    let small = Overrides::default().with("width", 48).with("height", 32).with("spp", 1).with("sharp_spp", 1);
    for name in &names {
        let toml = scenes.join(name).join("scene.toml");
        // the Cornell-box scenes take the default surface-cache frames. The big scenes take
        // path-traced thumbnails: their surface, shadow and glossy grids are laid at world-space
        // spacings that do not follow the resolution, so at 48x32 they would spend minutes per
        // scene filling points far finer than a pixel (their surface-cache frames are measured
        // by `evsim dataset-fidelity`, docs/fidelity.md)
        let over = if ["cbox", "tiny"].contains(&name.as_str()) {
            small.clone()
        } else {
            small.clone().with("shading", toml::Value::try_from(Shading::PathTraced).unwrap())
        };
        let plan = Plan::resolve(&toml, &over).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(plan.scene.warnings.is_empty(), "{name}: {:?}", plan.scene.warnings);
        let out = dir.join(name);
        let s = write_dataset(&plan, &RunOptions { out: out.clone(), ..RunOptions::default() })
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(s.events_on + s.events_off > 0, "{name}: no events");
        let policy = if plan.config.sharp_every == 8 { TestViewPolicy::Every8 } else { TestViewPolicy::Auto };
        let opts = CheckOptions { test_views: policy, events_unit: EventsUnit::Ns, ..CheckOptions::default() };
        let report = check_dataset(&out, &opts).unwrap();
        assert!(report.is_ok(), "{name}:\n{report}");
        let _ = std::fs::remove_dir_all(&out);
    }
}
