//! Blur models (issue 7 onwards). What lives where:
//! - [`awp`]: DP-NeRF's adaptive weight proposal (blending weights from what the rays see).
//! - [`dsk`]: Deblur-NeRF's deformable sparse kernel (per-pixel ray offsets, origin shifts and
//!   weights from an MLP over the image embedding, kernel point and pixel position).
//! - [`rigid`]: DP-NeRF's rigid blurring kernel heads (per-image twists and blending weights).
//! - [`trajectory`]: virtual cameras inside the exposure (BAD-NeRF learned, E2NeRF fixed).
//! - [`se3`]: the exponential map of se(3) twists to rigid motions, and its backward.

pub mod awp;
pub mod dsk;
pub mod rigid;
pub mod se3;
pub mod trajectory;

/// Most rays a pixel group can have (the origin ray and up to 31 warped rays).
pub const MAX_RAYS: usize = 32;

use self::awp::AwpConfig;
use self::dsk::DskConfig;
use self::rigid::RigidConfig;
use self::trajectory::TrajectoryConfig;

/// The blur model of a run and the iteration it starts at. In TOML (`[blur]`) it is `start`
/// and exactly one of `kernel` (with an optional `awp`), `dsk` and `trajectory`; reading
/// refuses any other combination, so the type holds one model.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "BlurToml", into = "BlurToml")]
pub struct BlurConfig {
    /// First iteration that renders the blur model's rays (reference: 1200; before it, one
    /// plain ray).
    pub start: u64,
    /// The model.
    pub model: BlurModel,
}

/// One blur model's settings.
#[derive(Clone, Debug, PartialEq)]
pub enum BlurModel {
    /// DP-NeRF's rigid blurring kernel (`blur.kernel`), optionally refined by the adaptive
    /// weight proposal (`blur.awp`).
    Rigid {
        /// The kernel.
        kernel: RigidConfig,
        /// The AWP (`None`: the kernel's weights only).
        awp: Option<AwpConfig>,
    },
    /// Deblur-NeRF's deformable sparse kernel, or PDRF's progressive one (`blur.dsk`).
    Dsk(DskConfig),
    /// Virtual cameras inside the exposure (`blur.trajectory`: BAD-NeRF learned, E2NeRF fixed).
    Trajectory(TrajectoryConfig),
}

impl BlurConfig {
    /// `model` from iteration `start`.
    pub fn new(start: u64, model: BlurModel) -> BlurConfig {
        BlurConfig { start, model }
    }

    /// The rigid kernel's settings, if that is the model.
    pub fn rigid(&self) -> Option<&RigidConfig> {
        match &self.model {
            BlurModel::Rigid { kernel, .. } => Some(kernel),
            _ => None,
        }
    }

    /// The adaptive weight proposal's settings, if the model is the rigid kernel with one.
    pub fn awp(&self) -> Option<&AwpConfig> {
        match &self.model {
            BlurModel::Rigid { awp, .. } => awp.as_ref(),
            _ => None,
        }
    }

    /// The deformable sparse kernel's settings, if that is the model.
    pub fn dsk(&self) -> Option<&DskConfig> {
        match &self.model {
            BlurModel::Dsk(d) => Some(d),
            _ => None,
        }
    }

    /// Checks every setting of the model (the error names the TOML key).
    pub fn validate(&self) -> Result<(), String> {
        match &self.model {
            BlurModel::Rigid { kernel, awp } => {
                kernel.validate()?;
                if let Some(a) = awp {
                    a.validate()?;
                }
            }
            BlurModel::Dsk(d) => {
                d.validate()?;
                if d.k + 1 > MAX_RAYS {
                    return Err(format!("blur.dsk.k = {}; at most {} kernel points", d.k, MAX_RAYS - 1));
                }
            }
            BlurModel::Trajectory(t) => t.validate()?,
        }
        Ok(())
    }
}

/// The TOML form of [`BlurConfig`]: the one-of is checked when it becomes a `BlurConfig`.
#[derive(Clone, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct BlurToml {
    #[serde(default)]
    kernel: Option<RigidConfig>,
    start: u64,
    #[serde(default)]
    awp: Option<AwpConfig>,
    #[serde(default)]
    dsk: Option<DskConfig>,
    #[serde(default)]
    trajectory: Option<TrajectoryConfig>,
}

impl TryFrom<BlurToml> for BlurConfig {
    type Error = String;

    fn try_from(t: BlurToml) -> Result<BlurConfig, String> {
        let model = match (t.kernel, t.awp, t.dsk, t.trajectory) {
            (Some(kernel), awp, None, None) => BlurModel::Rigid { kernel, awp },
            (None, None, Some(d), None) => BlurModel::Dsk(d),
            (None, None, None, Some(tr)) => BlurModel::Trajectory(tr),
            (None, Some(_), _, _) => {
                return Err("blur.awp refines the rigid kernel's weights; set blur.kernel or blur.awp = none".into())
            }
            _ => {
                return Err("blur: set exactly one of blur.kernel, blur.dsk and blur.trajectory (or blur = none)".into())
            }
        };
        Ok(BlurConfig { start: t.start, model })
    }
}

impl From<BlurConfig> for BlurToml {
    fn from(c: BlurConfig) -> BlurToml {
        let mut t = BlurToml { kernel: None, start: c.start, awp: None, dsk: None, trajectory: None };
        match c.model {
            BlurModel::Rigid { kernel, awp } => (t.kernel, t.awp) = (Some(kernel), awp),
            BlurModel::Dsk(d) => t.dsk = Some(d),
            BlurModel::Trajectory(tr) => t.trajectory = Some(tr),
        }
        t
    }
}
