//! The registry of training presets: every method is a named function of the scale, built from
//! component configs and derived from another preset where it differs in a few fields. The CLI,
//! the benchmark and the smoke tests all read [`PRESETS`].
//!
//! Scales:
//! - `paper`: the reference implementation's settings (`../shared/reference/method.md`):
//!   coarse VM 256^3 [64,16,16] -> 32, fine VM 512^3 [64,16,16] -> 32, MLP widths 64 / 256,
//!   64 + 64 samples, 1024 rays, 30 k iterations, lr 5e-3 decayed 10x per 10 k steps.
//! - `cpu`: sized for 2 cores and about 20 minutes (see [`cpu_model`] for the choices and why).

use crate::blur::awp::AwpConfig;
use crate::blur::dsk::DskConfig;
use crate::blur::rigid::RigidConfig;
use crate::blur::trajectory::TrajectoryConfig;
use crate::config::{BlurConfig, BlurModel, EventLossConfig, ImageSource, TrainConfig};
use crate::engine::adam::AdamConfig;
use crate::engine::field::FieldShape;
use crate::engine::model::{ModelConfig, VolumeShape};
use crate::engine::occupancy::OccupancyConfig;
use crate::events::ecrf::EcrfConfig;
use crate::events::edi::EdiConfig;

/// How big a run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scale {
    /// The reference hyper-parameters.
    Paper,
    /// Defaults chosen for a 2-core CPU.
    Cpu,
}

impl Scale {
    /// Parses `paper` or `cpu`.
    pub fn parse(s: &str) -> Option<Scale> {
        match s {
            "paper" => Some(Scale::Paper),
            "cpu" => Some(Scale::Cpu),
            _ => None,
        }
    }
}

/// A named method.
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    /// The name used on the command line and in tables.
    pub name: &'static str,
    /// One line on what it is.
    pub description: &'static str,
    /// Its configuration at a scale.
    pub build: fn(Scale) -> TrainConfig,
}

/// Every preset, in table order.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "nerf",
        description: "radiance field on the blurry images, no blur model (lower bound)",
        build: nerf,
    },
    Preset {
        name: "nerf-sharp",
        description: "radiance field on the sharp renders of the training views (upper bound)",
        build: nerf_sharp,
    },
    Preset {
        name: "ev-deblurnerf",
        description: "Ev-DeblurNeRF: rigid blur kernel + AWP, event loss, eCRF and EDI prior (full method)",
        build: ev_deblurnerf,
    },
    Preset {
        name: "ev-deblurnerf--",
        description: "Ev-DeblurNeRF without eCRF and EDI: rigid blur kernel and event loss",
        build: ev_deblurnerf_minus,
    },
    Preset {
        name: "e2nerf",
        description:
            "E2NeRF-style: fixed virtual cameras from the trajectory inside the exposure, events inside exposures",
        build: e2nerf,
    },
    Preset { name: "e-nerf", description: "E-NeRF: event loss and the blurry images, no blur model", build: e_nerf },
    Preset {
        name: "edi-nerf",
        description: "EDI + NeRF: images deblurred by the event double integral, then a plain radiance field",
        build: edi_nerf,
    },
    Preset { name: "dp-nerf", description: "DP-NeRF: rigid blur kernel + AWP, images only", build: dp_nerf },
    Preset {
        name: "deblur-nerf",
        description: "Deblur-NeRF: per-pixel deformable sparse kernel, images only",
        build: deblur_nerf,
    },
    Preset {
        name: "pdrf",
        description: "PDRF: progressive two-stage deformable kernel reading the coarse field's features, images only",
        build: pdrf,
    },
    Preset {
        name: "bad-nerf",
        description: "BAD-NeRF: learned camera trajectory (start and end poses) inside each exposure, images only",
        build: bad_nerf,
    },
];

/// The preset called `name`.
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// The names of every preset (for error messages).
pub fn names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.name).collect()
}

/// The reference MLPs of one level: PE with 10 / 4 frequencies, density MLP with one hidden
/// layer of `width`, `features` passed on, colour MLP with two hidden layers of `width`, no
/// biases.
fn reference_mlps(width: usize, features: usize) -> FieldShape {
    FieldShape {
        pe_pos: 10,
        pe_dir: 4,
        density_hidden: vec![width],
        features,
        colour_hidden: vec![width, width],
        bias: false,
    }
}

/// The reference model.
pub fn paper_model() -> ModelConfig {
    ModelConfig {
        coarse_volume: VolumeShape { res: 256, comps: [64, 16, 16], features: 32 },
        fine_volume: Some(VolumeShape { res: 512, comps: [64, 16, 16], features: 32 }),
        coarse: reference_mlps(64, 15),
        fine: Some(reference_mlps(256, 128)),
        n_coarse: 64,
        n_fine: 64,
        coarse_step: None,
        density_noise: 1.0,
        tv_plane: 1e-2 * 5.0,
        tv_line: 1e-3 * 5.0,
        explicit: true,
        dense: false,
        skip_threshold: 1e-4,
        occupancy: None,
        bounds: None,
    }
}

/// The 2-core model. Choices, and why (measured with `nerf-sharp` on `factory` at 300x200):
/// - one field level (the coarse shape) evaluating both passes: the fine level of the reference
///   (256-wide MLPs, 512^3 volume) costs ~10x the coarse per sample; one shared field keeps the
///   hierarchical sampling at a fraction of the cost;
/// - the reference coarse volume (~256^3, [64,16,16] components): at 3000 steps +0.46 dB test
///   PSNR over ~224^3, which was +0.85 dB over 160^3 with [48,12,12] (at 2000 steps);
/// - 48 stratified + 24 importance samples per ray: forward-facing scenes in NDC concentrate
///   the content in a thin depth range that importance sampling finds; 24 importance samples
///   instead of 48 make a step about 30% faster at the same test PSNR (8000 steps on factory:
///   nerf-sharp 30.09 against 30.13 dB, ev-deblurnerf 28.10 against 28.13 and within 0.12 dB
///   at every evaluation; `benchmark/results/2026-12-05-fine-samples.md`);
/// - more samples where the rays are longer (`coarse_step` 4.5 voxels): factory's longest ray
///   crosses 212 voxels of the coarse volume, which 48 samples step through 4.4 at a time;
///   trolley's camera sweeps far sideways, its rays cross up to 415, and it gets 93 + 47
///   (nerf-sharp at 2000 steps: 96 + 48 samples 24.35 dB against 23.20 at 48 + 24; factory
///   keeps 48 + 24; `benchmark/results/2026-12-07-samples-per-voxel.md`);
/// - density noise kept (1.0): without it the test PSNR at 1000 steps was 0.7 dB lower;
/// - everything else as the reference.
pub fn cpu_model() -> ModelConfig {
    let paper = paper_model();
    ModelConfig {
        coarse_volume: VolumeShape { res: 256, comps: [64, 16, 16], features: 32 },
        fine_volume: None,
        fine: None,
        n_coarse: 48,
        n_fine: 24,
        coarse_step: Some(4.5),
        occupancy: Some(OccupancyConfig { res: 64, every: 50, threshold: -4.0 }),
        ..paper
    }
}

/// The reference optimiser: lr 5e-3 for everything, decayed 10x per 10 k steps.
pub fn paper_adam() -> AdamConfig {
    AdamConfig {
        lr_volume: 5e-3,
        lr_network: 5e-3,
        lr_embedding: 5e-3,
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
        decay: 0.1,
        decay_steps: 10_000.0,
    }
}

/// Plain radiance field on the blurry images.
pub fn nerf(scale: Scale) -> TrainConfig {
    match scale {
        Scale::Paper => TrainConfig {
            model: paper_model(),
            adam: paper_adam(),
            iterations: 30_000,
            batch_rays: 1024,
            chunk_rays: 4,
            images: ImageSource::Blurry,
            response_gamma: 2.2,
            seed: 0,
            checkpoint_every: 1000,
            eval_every: 5000,
            threads: 0,
            blur: None,
            events: None,
            ecrf: None,
            edi: None,
        },
        Scale::Cpu => TrainConfig {
            model: cpu_model(),
            // About 20 minutes on 2 cores. TensoRF's schedule: the rate falls 10x over the whole
            // run (the reference's 1000x over 30 k steps left the last third of a short run
            // idle), and the volumes learn at TensoRF's 2e-2.
            adam: AdamConfig { lr_volume: 2e-2, decay_steps: 8000.0, ..paper_adam() },
            iterations: 8000,
            batch_rays: 1024,
            chunk_rays: 4,
            eval_every: 1000,
            ..nerf(Scale::Paper)
        },
    }
}

/// The reference rigid blurring kernel: K = 9 warped rays, 32-d embeddings and heads, twists
/// x 0.1, twist heads' last layers initialised at 1% of the PyTorch scale (near the identity).
pub fn rigid_reference() -> RigidConfig {
    RigidConfig { k: 9, embedding: 32, hidden: 32, twist_scale: 0.1, init_scale: 0.01 }
}

/// The 2-core AWP: the sample-embedding MLP at 2 x 32 instead of 4 x 64 (each pixel runs it on
/// (K + 1) x 96 samples; at the reference size it would cost more than the field), the mixing
/// schedule's steps scaled like the kernel start (10 k x 8000 / 30 000).
pub fn cpu_awp() -> AwpConfig {
    AwpConfig { sample_hidden: vec![32, 32], mix_every: 2667, ..AwpConfig::reference() }
}

/// Ev-DeblurNeRF (full). Paper scale: the reference settings (kernel and eCRF from iteration
/// 1200, 4096 events per batch, EDI 0.01 cosine-decayed to 1e-5 over 10 k steps). Cpu scale:
/// the `nerf` cpu field and budget (8000 iterations); per iteration 512 pixels x 6 rays (K = 5
/// warped rays and the origin ray) and 512 events x 2 rays (4x the rays of a `nerf` step;
/// with 256 pixels the test PSNR on factory 300x200 was 0.2-1.0 dB
/// lower at every 1000 steps, 26.90 against 27.21 dB at 8000); kernel and eCRF from 320
/// (1200 x 8000 / 30000); the EDI prior at the reference's real-data weight (1.0, constant):
/// path-traced events carry sampling noise, and at 300x200 a field trained on `evsim` data
/// explains only a small part of the single-event loss (see the issue-7 note), while the EDI
/// images are 6 dB closer to the sharp views than the blurry ones.
pub fn ev_deblurnerf(scale: Scale) -> TrainConfig {
    let base = nerf(scale);
    let edi = EdiConfig::reference_synthetic();
    match scale {
        Scale::Paper => TrainConfig {
            blur: Some(BlurConfig::new(
                1200,
                BlurModel::Rigid { kernel: rigid_reference(), awp: Some(AwpConfig::reference()) },
            )),
            events: Some(EventLossConfig::reference()),
            ecrf: Some(EcrfConfig::reference()),
            edi: Some(edi),
            ..base
        },
        Scale::Cpu => TrainConfig {
            batch_rays: 512,
            chunk_rays: 12,
            blur: Some(BlurConfig::new(
                320,
                BlurModel::Rigid { kernel: RigidConfig { k: 5, ..rigid_reference() }, awp: Some(cpu_awp()) },
            )),
            events: Some(EventLossConfig { batch: 512, ..EventLossConfig::reference() }),
            ecrf: Some(EcrfConfig { start: 320, ..EcrfConfig::reference() }),
            edi: Some(EdiConfig::reference_real()),
            ..base
        },
    }
}

/// Ev-DeblurNeRF-- : [`ev_deblurnerf`] without the eCRF and the EDI prior.
pub fn ev_deblurnerf_minus(scale: Scale) -> TrainConfig {
    TrainConfig { ecrf: None, edi: None, ..ev_deblurnerf(scale) }
}

/// The iteration at `paper` scale's `at` (of 30 000) scaled to the `cpu` budget (8000).
fn cpu_iteration(at: u64) -> u64 {
    at * 8000 / 30_000
}

/// DP-NeRF: [`ev_deblurnerf`]'s rigid kernel and AWP with the images only (no events, eCRF or
/// EDI), at the same pixels per step.
pub fn dp_nerf(scale: Scale) -> TrainConfig {
    TrainConfig { events: None, ecrf: None, edi: None, ..ev_deblurnerf(scale) }
}

/// Deblur-NeRF: the deformable sparse kernel (reference settings: K = 5, from iteration 1200,
/// alignment loss until 90% of the run). Cpu scale: 256 pixels x 5 rays per step, start and
/// alignment end scaled to the 8000-iteration budget.
pub fn deblur_nerf(scale: Scale) -> TrainConfig {
    let base = nerf(scale);
    let dsk = DskConfig { align_until: base.iterations * 9 / 10, ..DskConfig::reference() };
    match scale {
        Scale::Paper => TrainConfig { blur: Some(BlurConfig::new(1200, BlurModel::Dsk(dsk))), ..base },
        Scale::Cpu => TrainConfig {
            batch_rays: 256,
            chunk_rays: 12,
            blur: Some(BlurConfig::new(cpu_iteration(1200), BlurModel::Dsk(dsk))),
            ..base
        },
    }
}

/// PDRF: the progressive kernel (`blur::dsk`, reference `*_full` settings: K = 10, from
/// iteration 1200, no alignment loss) on the explicit + MLP field. Cpu scale: 256 pixels x 5
/// rays per step (plus 5 first-stage coarse rays each), start scaled to the 8000-iteration
/// budget.
pub fn pdrf(scale: Scale) -> TrainConfig {
    let base = nerf(scale);
    match scale {
        Scale::Paper => TrainConfig { blur: Some(BlurConfig::new(1200, BlurModel::Dsk(DskConfig::pdrf()))), ..base },
        Scale::Cpu => TrainConfig {
            batch_rays: 256,
            chunk_rays: 12,
            blur: Some(BlurConfig::new(cpu_iteration(1200), BlurModel::Dsk(DskConfig { k: 5, ..DskConfig::pdrf() }))),
            ..base
        },
    }
}

/// BAD-NeRF: per image a start and an end pose inside the exposure, learned from the first
/// iteration (both start at the dataset's pose), 7 virtual cameras (BAD-NeRF's synthetic
/// setting; cpu: 5, 256 pixels per step).
pub fn bad_nerf(scale: Scale) -> TrainConfig {
    let base = nerf(scale);
    let trajectory = |k| Some(BlurConfig::new(0, BlurModel::Trajectory(TrajectoryConfig { k, learned: true })));
    match scale {
        Scale::Paper => TrainConfig { blur: trajectory(7), ..base },
        Scale::Cpu => TrainConfig { batch_rays: 256, chunk_rays: 12, blur: trajectory(5), ..base },
    }
}

/// E2NeRF-style: the blurry colour is the mean of K virtual cameras at the dataset
/// trajectory's poses inside the exposure (fixed, nothing learned; paper K = 9, cpu 5), and
/// the event loss sees only pairs of consecutive events inside a training view's exposure
/// (single events at both scales: windows may not cross an exposure's end).
pub fn e2nerf(scale: Scale) -> TrainConfig {
    let base = ev_deblurnerf(scale);
    let k = if scale == Scale::Paper { 9 } else { 5 };
    TrainConfig {
        blur: Some(BlurConfig::new(0, BlurModel::Trajectory(TrajectoryConfig { k, learned: false }))),
        events: base.events.clone().map(|e| EventLossConfig {
            inside_exposures: true,
            window: None,
            window_ms: None,
            ..e
        }),
        ecrf: None,
        edi: None,
        ..base
    }
}

/// E-NeRF: the event loss (all pairs, as [`ev_deblurnerf`]'s) plus the image loss on the
/// blurry images, no blur model, no eCRF or EDI; the `nerf` field and pixels per step.
pub fn e_nerf(scale: Scale) -> TrainConfig {
    TrainConfig { events: ev_deblurnerf(scale).events, ..nerf(scale) }
}

/// EDI + NeRF: the `nerf` preset on the training views deblurred by the event double integral
/// (8 bins; model-based, no learning).
pub fn edi_nerf(scale: Scale) -> TrainConfig {
    TrainConfig { images: ImageSource::Edi, ..nerf(scale) }
}

/// Plain radiance field on the sharp renders of the training views.
pub fn nerf_sharp(scale: Scale) -> TrainConfig {
    TrainConfig { images: ImageSource::Sharp, ..nerf(scale) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_validates_at_both_scales_and_names_are_unique() {
        let mut seen = std::collections::HashSet::new();
        for p in PRESETS {
            assert!(seen.insert(p.name), "duplicate preset {}", p.name);
            for s in [Scale::Paper, Scale::Cpu] {
                (p.build)(s).validate().unwrap_or_else(|e| panic!("{} {s:?}: {e}", p.name));
            }
        }
    }

    #[test]
    fn paper_model_has_the_reference_sizes() {
        let m = crate::engine::model::Model::new(&paper_model());
        assert_eq!(m.coarse.density[0].n_in, 32 + 63);
        assert_eq!(m.coarse.colour[0].n_in, 15 + 27);
        let fine = m.fine.as_ref().unwrap();
        assert_eq!(fine.density[0].n_in, 127);
        assert_eq!(fine.colour[0].n_in, 128 + 27);
        // Voxel counts of the reference: 256^3 = 16.7 M and 512^3 = 134 M.
        assert_eq!(m.volumes[0].res.iter().product::<usize>(), 16_777_216);
        assert_eq!(m.volumes[1].res.iter().product::<usize>(), 134_217_728);
    }
}
