//! Training configuration: everything a run needs besides the dataset, as one serde struct that
//! a preset builds and a run folder records (`config.toml`). Unknown keys are rejected.

pub use crate::blur::{BlurConfig, BlurModel};
use crate::engine::adam::AdamConfig;
use crate::engine::model::ModelConfig;
use crate::events::ecrf::EcrfConfig;
use crate::events::edi::EdiConfig;
use simulator::base::settings::{apply_sets, SetWording};

/// Which images supervise the colour.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImageSource {
    /// The blurry training views of `images_1/`.
    Blurry,
    /// The sharp renders of the same views from `images_sharp_1/` (the upper bound).
    Sharp,
    /// The blurry views deblurred by the event double integral (EDI) from their exposure's
    /// events (`edi-nerf`; the settings of `[edi]` if present, else 8 bins).
    Edi,
    /// The blurry views deblurred by an external program before training (images in, images
    /// out): a shell command with `{input}` (the view's PNG in `images_1/`) and `{output}` (the
    /// PNG it must write, same size), e.g. `images = { deblur = "python mprnet.py {input} {output}" }`.
    Deblur(String),
}

/// A whole training run's settings.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// The radiance field and its sampling.
    pub model: ModelConfig,
    /// Optimiser and learning-rate schedule.
    pub adam: AdamConfig,
    /// Training iterations (reference: 30 000).
    pub iterations: u64,
    /// Image rays per iteration (reference: 1024).
    pub batch_rays: usize,
    /// Rays rendered per field call (more: bigger matrix products; fewer: less memory).
    pub chunk_rays: usize,
    /// Which images supervise the colour.
    pub images: ImageSource,
    /// Camera response exponent: the network's linear colour c is shown as c^(1/gamma)
    /// (reference synthetic data: 2.2).
    pub response_gamma: f64,
    /// Seed of initialisation, ray batches, jitter and density noise.
    pub seed: u64,
    /// Write a checkpoint every this many iterations (and at the end).
    pub checkpoint_every: u64,
    /// Evaluate the test views every this many iterations for the log (0: only at the end).
    pub eval_every: u64,
    /// Worker threads (0: all cores). Results are bit-reproducible for a given count.
    pub threads: usize,
    /// The blur model (`None`: one plain ray per pixel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blur: Option<BlurConfig>,
    /// The event loss (`None`: images only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub events: Option<EventLossConfig>,
    /// The learnable event camera response (`None`: the identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ecrf: Option<EcrfConfig>,
    /// The event double integral prior (`None`: off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edi: Option<EdiConfig>,
}

/// The event loss, event by event (module `trainer::method`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventLossConfig {
    /// Events per iteration (reference synthetic: 4096; each renders two rays).
    pub batch: usize,
    /// Weight of the loss (reference: 0.1).
    pub weight: f64,
    /// Training contrast thresholds (ON, OFF) in log intensity; `None`: the dataset's
    /// (`dataset.toml` `[event_model]`), else the reference 0.2. A value different from the
    /// simulation's is the threshold-mismatch study.
    pub threshold: Option<[f64; 2]>,
    /// Offset in `log(L + eps)`; `None`: the dataset's `log_eps`, else the reference 1e-5.
    pub log_eps: Option<f64>,
    /// Luma weights of monochrome events; `None`: the dataset's sensor (ours: Rec.709), else
    /// the reference BT.601 (0.299, 0.587, 0.114).
    pub luma: Option<[f64; 3]>,
    /// Colour events (L_ev-color): each event sees its RGGB Bayer channel, weighted R 0.4,
    /// G 0.2, B 0.4, instead of luma.
    pub colour: bool,
    /// Supervise only pairs of events inside one training view's exposure (E2NeRF-style)
    /// instead of every pair (the reference).
    pub inside_exposures: bool,
    /// Event windows (the reference's `event_accumulate_step_range`): each pair hops a number
    /// of events at its pixel drawn uniformly in `[min, max]` (fewer where the pixel's events or
    /// the trajectory end first) and its target is the hopped events' polarities times their
    /// thresholds, summed; `None`: single events (one hop, the reference default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<[u32; 2]>,
    /// Longest event window (ms): a window stops before an event more than this long after
    /// its first event (its first hop is always taken, so a pair is never lost); `None`: no
    /// limit. Only with `window`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_ms: Option<f64>,
    /// Saturated pairs: drop a pair when its rendered luma (the linear colour, before the
    /// eCRF) reaches this value at either end, where a sigmoid colour cannot follow the
    /// events' change; `None`: every pair counts (docs/trainer.md, "radiance above 1").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturation: Option<f64>,
    /// Dark pairs: drop a pair when its rendered linear luma is below this value at either
    /// end, where `log(L + eps)` is steepest; `None`: every pair counts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dark: Option<f64>,
    /// Robust event loss: the Huber loss with this transition (in log intensity) instead of the
    /// square, so a pair the field cannot explain pulls with at most `2 huber`; `None`: the
    /// squared error (the reference).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub huber: Option<f64>,
}

/// Most events an event window ([`EventLossConfig::window`]) hops.
pub const MAX_EVENT_WINDOW: u32 = 1000;

/// Most rays (image or event) one training step may take: far above any preset's 1024, far
/// below what would exhaust memory.
pub const MAX_BATCH: usize = 1 << 20;

impl EventLossConfig {
    /// The reference synthetic-data settings (dataset-derived values left to resolve).
    pub fn reference() -> EventLossConfig {
        EventLossConfig {
            batch: 4096,
            weight: 0.1,
            threshold: None,
            log_eps: None,
            luma: None,
            colour: false,
            inside_exposures: false,
            window: None,
            window_ms: None,
            saturation: None,
            dark: None,
            huber: None,
        }
    }
}

impl TrainConfig {
    /// Whether training reads the dataset's events (event loss, EDI prior or EDI images).
    pub fn needs_events(&self) -> bool {
        self.events.is_some() || self.edi.is_some() || self.images == ImageSource::Edi
    }

    /// Checks values a preset or a hand-edited `config.toml` could get wrong; the message names
    /// the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        let m = &self.model;
        let positive = [
            ("iterations", self.iterations as f64),
            ("batch_rays", self.batch_rays as f64),
            ("chunk_rays", self.chunk_rays as f64),
            ("checkpoint_every", self.checkpoint_every as f64),
            ("response_gamma", self.response_gamma),
            ("model.n_coarse", m.n_coarse as f64 - 2.0),
            ("model.coarse_volume.res", m.coarse_volume.res as f64 - 1.0),
            ("adam.decay_steps", self.adam.decay_steps),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} is out of range; it must be a positive number (n_coarse >= 3, res >= 2)"));
            }
        }
        if let Some(step) = m.coarse_step {
            if !(step.is_finite() && step >= 0.25) {
                return Err(format!(
                    "model.coarse_step = {step}; it must be a number of voxels >= 0.25 (the cpu presets use 4.5), or none for the counts as given"
                ));
            }
        }
        // a step holds every ray's samples in memory: a mistyped batch would abort on allocation
        for (name, v) in
            [("batch_rays", self.batch_rays), ("events.batch", self.events.as_ref().map_or(1, |e| e.batch))]
        {
            if v > MAX_BATCH {
                return Err(format!("{name} = {v}; at most {MAX_BATCH} rays per step (the presets use 1024)"));
            }
        }
        let volumes = [("model.coarse_volume", Some(&m.coarse_volume)), ("model.fine_volume", m.fine_volume.as_ref())];
        for (name, v) in volumes.into_iter().filter_map(|(n, v)| v.map(|v| (n, v))) {
            if v.comps.contains(&0) || v.features == 0 {
                return Err(format!(
                    "{name}.comps = {:?}, features = {}; every count must be >= 1",
                    v.comps, v.features
                ));
            }
        }
        if !(0.0..1.0).contains(&m.skip_threshold) {
            return Err(format!(
                "model.skip_threshold = {}; it must be in [0, 1) (the presets use 1e-4, 0 colours every sample)",
                m.skip_threshold
            ));
        }
        if let Some(o) = &m.occupancy {
            if !(2..=512).contains(&o.res) || o.every == 0 || !o.threshold.is_finite() {
                return Err(format!(
                    "model.occupancy = {{ res = {}, every = {}, threshold = {} }}; res must be in [2, 512], every >= 1 and the threshold finite (the cpu presets use 64, 50, -4; drop the table to evaluate every sample)",
                    o.res, o.every, o.threshold
                ));
            }
        }
        let non_negative = [
            ("model.density_noise", m.density_noise),
            ("model.tv_plane", m.tv_plane),
            ("model.tv_line", m.tv_line),
            ("adam.lr_volume", self.adam.lr_volume),
            ("adam.lr_network", self.adam.lr_network),
            ("adam.lr_embedding", self.adam.lr_embedding),
            ("adam.eps", self.adam.eps),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} = {v}; it must be a finite number >= 0"));
            }
        }
        if let Some(b) = &m.bounds {
            let ok = (0..3).all(|i| b.min[i].is_finite() && b.max[i].is_finite() && b.min[i] < b.max[i]);
            if !ok {
                return Err(format!(
                    "model.bounds = {{ min = {:?}, max = {:?} }}; each min must be below its max, all finite (or drop it to fit the box to the cameras)",
                    b.min, b.max
                ));
            }
        }
        for (name, b) in
            [("adam.beta1", self.adam.beta1), ("adam.beta2", self.adam.beta2), ("adam.decay", self.adam.decay)]
        {
            if !(0.0..=1.0).contains(&b) {
                return Err(format!("{name} = {b}; it must be in [0, 1]"));
            }
        }
        if let ImageSource::Deblur(cmd) = &self.images {
            if !(cmd.contains("{input}") && cmd.contains("{output}")) {
                return Err(format!(
                    "images.deblur = {cmd:?}; the command must contain {{input}} and {{output}} (the blurry PNG it reads and the PNG it writes)"
                ));
            }
        }
        if let Some(b) = &self.blur {
            b.validate()?;
        }
        if let Some(e) = &self.events {
            if e.batch == 0 {
                return Err("events.batch = 0; it must be >= 1 (or drop [events] for images only)".into());
            }
            if let Some([lo, hi]) = e.window {
                if !(1 <= lo && lo <= hi && hi <= MAX_EVENT_WINDOW) {
                    return Err(format!(
                        "events.window = [{lo}, {hi}]; it must be [min, max] hops with 1 <= min <= max <= {MAX_EVENT_WINDOW} (or none for single events)"
                    ));
                }
                if e.inside_exposures {
                    return Err("events.window with events.inside_exposures = true: windows of events inside exposures are not supported; drop one of them".into());
                }
            }
            if let Some(ms) = e.window_ms {
                if !(ms.is_finite() && ms > 0.0) {
                    return Err(format!("events.window_ms = {ms}; it must be a positive number of milliseconds"));
                }
                if e.window.is_none() {
                    return Err("events.window_ms without events.window: it limits event windows; set events.window = [min, max] too, or drop it".into());
                }
            }
            let mut checks = vec![("events.weight", e.weight, true)];
            if let Some([on, off]) = e.threshold {
                checks.extend([("events.threshold[0]", on, false), ("events.threshold[1]", off, false)]);
            }
            if let Some(limit) = e.saturation {
                checks.push(("events.saturation", limit, false));
            }
            if let Some(limit) = e.dark {
                checks.push(("events.dark", limit, false));
            }
            if let Some(delta) = e.huber {
                checks.push(("events.huber", delta, false));
            }
            if let Some(eps) = e.log_eps {
                checks.push(("events.log_eps", eps, false));
            }
            if let Some(l) = e.luma {
                checks.extend(l.iter().map(|&v| ("events.luma", v, true)));
            }
            for (name, v, zero_ok) in checks {
                if !(v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0))) {
                    return Err(format!(
                        "{name} = {v}; it must be a finite number > 0{}",
                        if zero_ok { " or 0" } else { "" }
                    ));
                }
            }
        }
        if let Some(c) = &self.ecrf {
            if c.hidden == 0 || c.layers == 0 || !(c.scale.is_finite() && c.scale >= 0.0) {
                return Err("ecrf: hidden and layers must be >= 1 and scale a finite number >= 0".into());
            }
            if self.events.is_none() {
                return Err("ecrf is set but [events] is not: the eCRF only acts on the event loss; add [events] or drop [ecrf]".into());
            }
        }
        if let Some(d) = &self.edi {
            d.validate()?;
        }
        Ok(())
    }
}

/// Applies `KEY=VALUE` overrides to a configuration: KEY is a dotted path into the TOML form
/// (`evtrain presets --show NAME`), VALUE a TOML value (`0.3`, `true`, `[0.3, 0.3]`; a bare word
/// is a string) or `none` to switch an optional part off (`ecrf=none`). Unknown keys and
/// values of the wrong type are refused; the result is validated.
pub fn apply_overrides(cfg: &TrainConfig, sets: &[String]) -> Result<TrainConfig, String> {
    let mut root = toml::Table::try_from(cfg).map_err(|e| format!("cannot represent the configuration: {e}"))?;
    let wording = SetWording {
        flag: "--set",
        example: "events.colour=true or ecrf=none",
        missing: "off in the preset, or misspelt; see evtrain presets --show NAME",
        create_tables: false,
    };
    apply_sets(&mut root, sets, wording)?;
    let out: TrainConfig = root.try_into().map_err(|e| format!("--set: {e}"))?;
    out.validate()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::{preset, Scale};

    fn base() -> TrainConfig {
        (preset("ev-deblurnerf").expect("preset").build)(Scale::Cpu)
    }

    #[test]
    fn overrides_set_values_switch_parts_off_and_refuse_mistakes() {
        let sets = |s: &[&str]| apply_overrides(&base(), &s.iter().map(|x| x.to_string()).collect::<Vec<_>>());
        let c =
            sets(&["events.colour=true", "events.threshold=[0.3, 0.25]", "ecrf=none", "model.explicit=false"]).unwrap();
        let e = c.events.as_ref().unwrap();
        assert!(e.colour && e.threshold == Some([0.3, 0.25]));
        assert!(c.ecrf.is_none() && !c.model.explicit);
        assert_eq!(sets(&["iterations=12"]).unwrap().iterations, 12);
        // Event windows: a hop range, refused out of order, zero or with inside_exposures.
        assert_eq!(sets(&["events.window=[2, 8]"]).unwrap().events.unwrap().window, Some([2, 8]));
        assert_eq!(sets(&["events.saturation=0.95"]).unwrap().events.unwrap().saturation, Some(0.95));
        let e = sets(&["events.dark=0.02", "events.huber=0.3"]).unwrap().events.unwrap();
        assert_eq!((e.dark, e.huber), (Some(0.02), Some(0.3)));
        // The training images: EDI-deblurred, or an external program's.
        assert_eq!(sets(&["images=edi"]).unwrap().images, ImageSource::Edi);
        let c = sets(&[r#"images={deblur="mprnet {input} {output}"}"#]).unwrap();
        assert_eq!(c.images, ImageSource::Deblur("mprnet {input} {output}".into()));
        assert!(sets(&[r#"images={deblur="mprnet"}"#]).unwrap_err().contains("{output}"));
        for (bad, says) in [
            (&["events.colur=true"][..], "colur"),
            (&["ecrf=none", "ecrf.polarity=false"][..], "`ecrf` is not in this configuration"),
            (&["iterations=many"][..], "iterations"),
            (&["events.weight=-1"][..], "events.weight"),
            (&["events.window=[0, 2]"][..], "events.window = [0, 2]"),
            (&["events.window=[4, 2]"][..], "1 <= min <= max"),
            (&["events.window=[1, 5000]"][..], "<= 1000"),
            (&["events.window=[1, 4]", "events.inside_exposures=true"][..], "inside_exposures"),
            (&["events.window=[2, 8]", "events.window_ms=0"][..], "events.window_ms = 0"),
            (&["events.window=[2, 8]", "events.window_ms=nan"][..], "events.window_ms = NaN"),
            (&["events.window_ms=4"][..], "without events.window"),
            (&["events.saturation=0"][..], "events.saturation = 0"),
            (&["events.saturation=nan"][..], "events.saturation = NaN"),
            (&["events.dark=-0.1"][..], "events.dark = -0.1"),
            (&["events.huber=0"][..], "events.huber = 0"),
            (&["events.huber=inf"][..], "events.huber = inf"),
            (&["batch_rays"][..], "KEY=VALUE"),
            (&["model.bounds={min=[0.0, 0.0, 0.0], max=[1.0, -1.0, 1.0]}"][..], "each min must be below its max"),
            (&["model.bounds={min=[0.0, 0.0, 0.0], max=[1.0, 1.0, nan]}"][..], "model.bounds"),
        ] {
            let err = sets(bad).unwrap_err();
            assert!(err.contains(says), "{bad:?}: {err}");
        }
    }

    #[test]
    fn blur_holds_one_model_and_reads_and_writes_the_toml_form() {
        let sets = |s: &[&str]| apply_overrides(&base(), &s.iter().map(|x| x.to_string()).collect::<Vec<_>>());
        // The TOML keeps `start` beside the model's own table; the AWP sits beside the kernel.
        let text = toml::to_string(&base()).unwrap();
        let blur = &text[text.find("[blur]").expect("[blur] table")..];
        assert!(blur.starts_with("[blur]\nstart = 320\n"), "{blur}");
        assert!(text.contains("[blur.kernel]\nk = 5\n") && text.contains("[blur.awp]\n"), "{text}");
        assert!(!text.contains("[blur.dsk]") && !text.contains("[blur.trajectory]"));
        let back: TrainConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, base());
        match &base().blur.unwrap().model {
            BlurModel::Rigid { kernel, awp } => assert!(kernel.k == 5 && awp.is_some()),
            other => panic!("ev-deblurnerf's blur model: {other:?}"),
        }
        // Switching models goes through `none`: the kernel and its AWP off, a trajectory on.
        let c = sets(&["blur.kernel=none", "blur.awp=none", "blur.trajectory={k=5, learned=false}"]).unwrap();
        let blur = c.blur.unwrap();
        assert_eq!(blur.start, 320);
        assert!(matches!(blur.model, BlurModel::Trajectory(t) if t.k == 5 && !t.learned));
        let c = sets(&["blur.kernel.k=7"]).unwrap();
        assert_eq!(c.blur.as_ref().and_then(|b| b.rigid()).map(|k| k.k), Some(7));
        for (bad, says) in [
            (&["blur.trajectory={k=5, learned=false}"][..], "exactly one of blur.kernel"),
            (&["blur.kernel=none", "blur.awp=none"][..], "exactly one of blur.kernel"),
            (&["blur.kernel=none"][..], "blur.awp refines the rigid kernel"),
            (&["blur.kernel.k=0"][..], "blur.kernel: k, embedding and hidden"),
            (&["blur.kernel.k=40"][..], "at most 31 warped rays"),
            (&["blur.kernel.twist_scale=nan"][..], "blur.kernel.twist_scale = NaN"),
            (&["blur.wobble=1"][..], "wobble"),
        ] {
            let err = sets(bad).unwrap_err();
            assert!(err.contains(says), "{bad:?}: {err}");
        }
        let dsk = (preset("deblur-nerf").expect("preset").build)(Scale::Cpu);
        assert!(dsk.blur.as_ref().is_some_and(|b| b.dsk().is_some() && b.rigid().is_none()));
        let over = |s: &str| apply_overrides(&dsk, &[s.to_string()]);
        assert!(over("blur.dsk.k=40").unwrap_err().contains("at most 31 kernel points"));
        let kernel = "blur.kernel={k=5, embedding=32, hidden=32, twist_scale=0.1, init_scale=0.01}";
        assert!(over(kernel).unwrap_err().contains("exactly one of blur.kernel"));
    }
}
