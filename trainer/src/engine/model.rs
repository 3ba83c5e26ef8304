//! A radiance-field model: coarse and (optionally) fine levels over shared VM volumes, its
//! sampling settings and the flat parameter layout.
//!
//! Reference shape (`../shared/reference/method.md`): coarse = one VM volume (~256^3, [64,16,16]
//! components, 32 features) + density MLP 95 -> 64 -> 1+15 + colour MLP 42 -> 64 -> 64 -> 3;
//! fine = the coarse volume and a second, larger one (~512^3), density MLP 127 -> 256 -> 1+128,
//! colour MLP 155 -> 256 -> 256 -> 3. Without a fine level the coarse field also evaluates the
//! importance samples (one network, two sampling passes).

use super::field::{Field, FieldShape};
use super::occupancy::{OccupancyConfig, OccupancyGrid};
use super::params::Layout;
use super::rng::Rng;
use super::vm::VmVolume;

/// Shape of one VM volume.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeShape {
    /// About `res^3` voxels, cubic, over the model's bounds (see [`Aabb::grid`]).
    pub res: usize,
    /// Components of the three plane-line pairs (reference coarse: [64, 16, 16]).
    pub comps: [usize; 3],
    /// Features after the basis matrix (reference: 32).
    pub features: usize,
}

/// An axis-aligned box in NDC.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabb {
    /// Minimum corner.
    pub min: [f64; 3],
    /// Maximum corner.
    pub max: [f64; 3],
}

impl Aabb {
    /// NDC's unit box [-1, 1]^3 (the reference camera's frustum from the near plane to infinity).
    pub const UNIT: Aabb = Aabb { min: [-1.0; 3], max: [1.0; 3] };

    /// Grid points per axis for about `res^3` cubic voxels over the box (TensoRF's
    /// `N_to_reso`): res_a = round(res * extent_a / cbrt(prod extents)), at least 2.
    pub fn grid(&self, res: usize) -> [usize; 3] {
        let e: [f64; 3] = std::array::from_fn(|a| (self.max[a] - self.min[a]).max(1e-9));
        let g = (e[0] * e[1] * e[2]).cbrt();
        std::array::from_fn(|a| ((res as f64 * e[a] / g).round() as usize).max(2))
    }
}

/// Everything that fixes the model's parameters and how rays are sampled.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// The coarse volume (read by both levels).
    pub coarse_volume: VolumeShape,
    /// The fine level's own volume (reference: ~512^3); `None`: the fine level reads only the
    /// coarse volume.
    pub fine_volume: Option<VolumeShape>,
    /// The coarse level's MLPs.
    pub coarse: FieldShape,
    /// The fine level's MLPs; `None`: one field for both passes.
    pub fine: Option<FieldShape>,
    /// Stratified samples per ray (reference: 64).
    pub n_coarse: usize,
    /// Importance samples per ray added for the fine pass (reference: 64).
    pub n_fine: usize,
    /// Longest stratified step, in voxels of the coarse volume, along the dataset's longest
    /// camera ray: when set, a run raises `n_coarse` until that ray gets a sample at least
    /// this often, and `n_fine` in proportion (`trainer::method::rays::sample_counts`), and
    /// records the counts it used. `None`: the counts as given (the reference).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coarse_step: Option<f64>,
    /// Standard deviation of the density noise in training (reference: 1.0).
    pub density_noise: f64,
    /// TV weight on the planes (reference: 1e-2 x 5).
    pub tv_plane: f64,
    /// TV weight on the lines (reference: 1e-3 x 5).
    pub tv_line: f64,
    /// Explicit VM volumes on (the reference) or off (an MLP-only field, Table 3's "without
    /// V_c,f" row; the MLPs then see only the positional encoding).
    #[serde(default = "explicit_default")]
    pub explicit: bool,
    /// Evaluate every sample through the whole field, as the engine did before it skipped
    /// samples ([`renderer`](super::renderer)'s module doc): the same result up to rounding and
    /// the density-noise draw, slower; kept to compare against.
    #[serde(default)]
    pub dense: bool,
    /// What a sample must weigh to be worked on (1e-4 in the presets): a ray ends before its
    /// first sample of transmittance below it (early ray termination, as Instant-NGP's), and a
    /// sample whose render weight is at or below it in every pass that renders it gets no
    /// colour (TensoRF's `rayMarch_weight_thres`): it adds nothing to the pixel instead of at
    /// most this weight times its colour, the colour MLP skips it forward and backward, and
    /// only its density passes gradients. The gradients are exact for the rendering so
    /// truncated. 0 works on every sample (the exact result up to rounding; what runs without
    /// this key did). Ignored with `dense`.
    #[serde(default)]
    pub skip_threshold: f64,
    /// Empty-space skipping ([`occupancy`](super::occupancy)): samples in cells of the grid
    /// that hold no density skip the field. `None`: every sample is evaluated (what runs
    /// without this key did). Ignored with `dense`.
    #[serde(default)]
    pub occupancy: Option<OccupancyConfig>,
    /// The NDC box the volumes cover; `None` in a preset means "fit it to the dataset's
    /// cameras" (`trainer::method::rays::scene_bounds`), and a run records the resolved box.
    pub bounds: Option<Aabb>,
}

fn explicit_default() -> bool {
    true
}

/// A built model: layout and levels (the parameters live in a separate flat vector).
#[derive(Clone, Debug)]
pub struct Model {
    /// The configuration it was built from.
    pub config: ModelConfig,
    /// Parameter layout.
    pub layout: Layout,
    /// Every VM volume (coarse first).
    pub volumes: Vec<VmVolume>,
    /// The coarse level.
    pub coarse: Field,
    /// The fine level (`None`: the coarse level evaluates the fine samples too).
    pub fine: Option<Field>,
    /// The current occupancy grid (training state, rebuilt as `config.occupancy` says; `None`:
    /// not built yet, or not configured).
    pub occupancy: Option<OccupancyGrid>,
}

impl Model {
    /// Builds the layout of `config`.
    pub fn new(config: &ModelConfig) -> Model {
        let mut layout = Layout::default();
        let b = config.bounds.unwrap_or(Aabb::UNIT);
        let vs = |l: &mut Layout, name: &str, s: &VolumeShape| {
            VmVolume::new(l, name, b.grid(s.res), s.comps, s.features, (b.min, b.max))
        };
        let mut volumes = Vec::new();
        if config.explicit {
            volumes.push(vs(&mut layout, "coarse.vm", &config.coarse_volume));
        }
        let coarse = Field::new(&mut layout, "coarse", volumes.clone(), config.coarse.clone());
        let fine = config.fine.as_ref().map(|shape| {
            let mut reads = volumes.clone();
            if let (Some(s), true) = (&config.fine_volume, config.explicit) {
                let fv = vs(&mut layout, "fine.vm", s);
                volumes.push(fv.clone());
                reads.push(fv);
            }
            Field::new(&mut layout, "fine", reads, shape.clone())
        });
        Model { config: config.clone(), layout, volumes, coarse, fine, occupancy: None }
    }

    /// The level that evaluates the fine samples.
    pub fn fine_field(&self) -> &Field {
        self.fine.as_ref().unwrap_or(&self.coarse)
    }

    /// Fresh parameters from `seed`: volumes 0.1 N(0, 1), layers PyTorch-uniform.
    pub fn init(&self, seed: u64) -> Vec<f32> {
        let mut params = self.layout.zeros::<f32>();
        let mut rng = Rng::new(seed, 0x1417);
        let mut normal_rng = Rng::new(seed, 0x1418);
        for v in &self.volumes {
            v.init(&mut params, &mut || normal_rng.normal_f64(), &mut || rng.uniform_f64());
        }
        self.coarse.init_mlps(&mut params, &mut || rng.uniform_f64());
        if let Some(f) = &self.fine {
            f.init_mlps(&mut params, &mut || rng.uniform_f64());
        }
        params
    }

    /// TV regulariser of every volume: adds its gradient to `grads` (the loss itself is not
    /// summed: training never reads it; [`VmVolume::tv`] gives it).
    pub fn tv(&self, params: &[f32], grads: &mut [f32]) {
        if self.config.tv_plane == 0.0 && self.config.tv_line == 0.0 {
            return;
        }
        for v in &self.volumes {
            v.tv_grad(params, grads, self.config.tv_plane, self.config.tv_line);
        }
    }

    /// The box the volumes (and the occupancy grid) cover.
    pub fn bounds(&self) -> Aabb {
        self.config.bounds.unwrap_or(Aabb::UNIT)
    }

    /// Whether training step `step` (about to run) rebuilds the occupancy grid: on the configured
    /// schedule, and whenever there is none yet.
    pub fn occupancy_due(&self, step: u64) -> bool {
        match &self.config.occupancy {
            Some(c) if !self.config.dense => self.occupancy.is_none() || step.is_multiple_of(c.every),
            _ => false,
        }
    }

    /// Rebuilds the occupancy grid from `params` for step `step` (see [`occupancy_due`](Self::occupancy_due)).
    pub fn rebuild_occupancy(&mut self, params: &[f32], seed: u64, step: u64) {
        if let Some(c) = &self.config.occupancy {
            self.occupancy = Some(OccupancyGrid::build(self, params, self.bounds(), c, seed, step));
        }
    }

    /// Installs a saved grid's bits (from a checkpoint); an error says why they do not fit this
    /// model's grid.
    pub fn set_occupancy_bits(&mut self, bits: Option<Vec<u64>>) -> Result<(), String> {
        let (Some(c), Some(bits)) = (&self.config.occupancy, bits) else {
            self.occupancy = None;
            return Ok(());
        };
        let dims = self.bounds().grid(c.res);
        if bits.len() != OccupancyGrid::words(dims) {
            return Err(format!(
                "its occupancy grid has {} words, model.occupancy.res = {} needs {}",
                bits.len(),
                c.res,
                OccupancyGrid::words(dims)
            ));
        }
        self.occupancy = Some(OccupancyGrid { dims, bounds: self.bounds(), bits });
        Ok(())
    }

    /// Samples per ray of the fine pass (coarse + importance).
    pub fn samples_fine(&self) -> usize {
        self.config.n_coarse + self.config.n_fine
    }
}
