//! Diagnostic: how well a trained run's field explains the dataset's events.
//! `cargo run --release -p evblur-trainer --example event_check -- RUN [N]`
use std::path::Path;
use trainer::checkpoint::Checkpoint;
use trainer::data::dataset::{Dataset, LoadOptions};
use trainer::engine::renderer::{RayChunk, Renderer};
use trainer::engine::rng::Rng;
use trainer::method::{resolve, Method};
use trainer::train::{prepare, unzip, RunPaths};

#[derive(serde::Deserialize)]
struct Record {
    data: std::path::PathBuf,
    config: trainer::config::TrainConfig,
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let run = RunPaths::new(Path::new(&args[1]));
    let n: usize = args.get(2).map_or(4096, |s| s.parse().unwrap());
    let rec: Record = toml::from_str(&std::fs::read_to_string(run.config())?)?;
    let data = Dataset::load(&rec.data, &LoadOptions::default())?;
    let mut cfg = rec.config.clone();
    cfg.events = Some(trainer::config::EventLossConfig::reference());
    resolve(&mut cfg, &data);
    let ev = cfg.events.clone().unwrap();
    println!("threshold {:?} log_eps {:?} luma {:?}", ev.threshold, ev.log_eps, ev.luma);
    let method = Method::new(&rec.config, data.views.len());
    let ck = Checkpoint::load(method.layout(), &run.checkpoint())?;
    let cands = trainer::method::event_candidates(&data, &data.split.train, false);
    let shift: f64 = args.get(3).map_or(0.0, |s| s.parse().unwrap());
    let pix: f64 = args.get(4).map_or(0.5, |s| s.parse().unwrap());
    let mut rng = Rng::new(1, 2);
    let mut rays = Vec::new();
    let mut pols = Vec::new();
    let mut dts = Vec::new();
    for _ in 0..n {
        let j = cands[rng.below(cands.len() as u64) as usize] as usize;
        let k = data.events.successor(j).unwrap();
        let (x, y) = (data.events.x[j] as f64 + pix, data.events.y[j] as f64 + pix);
        for t in [data.events.t_us[j], data.events.t_us[k]] {
            let t = (t + shift).clamp(data.trajectory.range_us().0, data.trajectory.range_us().1);
            let pose = data.trajectory.pose_at(t).unwrap();
            rays.push(prepare(&data, &data.intrinsics.ray_through(&pose, x, y)));
        }
        pols.push(data.events.polarity[k]);
        dts.push(data.events.t_us[k] - data.events.t_us[j]);
    }
    let mut r = Renderer::default();
    let mut cols = Vec::new();
    for c in rays.chunks(64) {
        let (o, d, v) = unzip(c);
        r.forward(&method.model, &ck.params, &RayChunk { origins: &o, dirs: &d, viewdirs: &v }, None);
        cols.extend_from_slice(r.fine());
    }
    let [th_on, th_off] = ev.threshold.unwrap();
    let luma = ev.luma.unwrap();
    let eps = ev.log_eps.unwrap();
    let (mut sq, mut sq0, mut sign_ok, mut big) = (0.0, 0.0, 0, 0);
    for e in 0..n {
        let l = |c: [f32; 3]| (0..3).map(|i| luma[i] * c[i] as f64).sum::<f64>();
        let d = (l(cols[2 * e + 1]) + eps).ln() - (l(cols[2 * e]) + eps).ln();
        let th = if pols[e] > 0 { th_on } else { th_off };
        let target = pols[e] as f64 * th;
        sq += (d - target).powi(2);
        sq0 += target * target;
        sign_ok += (d * target > 0.0) as usize;
        big += (d.abs() > 0.5 * th) as usize;
    }
    let mut dts2 = dts.clone();
    dts2.sort_by(f64::total_cmp);
    println!(
        "events {n}: mean r^2 {:.5} (zero-change model {:.5}); sign agrees {:.1}%; |dlog| > theta/2: {:.1}%; median gap {:.0} us",
        sq / n as f64,
        sq0 / n as f64,
        100.0 * sign_ok as f64 / n as f64,
        100.0 * big as f64 / n as f64,
        dts2[n / 2]
    );
    Ok(())
}
