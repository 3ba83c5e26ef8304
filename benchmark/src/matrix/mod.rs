//! The run matrix: a TOML file of methods x scenes x seeds ([`config`]), resolved into cells
//! with keys before any work starts ([`plan`]), the content hashes behind the keys
//! ([`identity`]) and the deterministic split of the cells among array jobs ([`shard`]).

pub mod config;
pub mod identity;
pub mod plan;
pub mod shard;

pub use config::MatrixConfig;
pub use plan::{Cell, MatrixPlan, MethodPlan, ScenePlan, SceneSource};
pub use shard::Shard;
