//! Content identities: the SHA-256 keys that name cells and simulated datasets.
//!
//! - A **dataset identity** is the simulator's settings hash for a scene to simulate (scene
//!   content + every dataset and event setting; `simulator::dataset::plan`), the manifest's
//!   `settings_hash` for a folder that has a `dataset.toml` (ours), and otherwise a hash of the
//!   folder's files: each file's relative path and size, and the bytes of every file up to
//!   [`CONTENT_LIMIT`] (larger ones, in practice `events.h5`, by size only). Hidden entries are
//!   skipped.
//! - A **cell key** hashes the preset name, the scale, the dataset identity and the training
//!   configuration with the seed and the overrides applied, before the dataset-dependent
//!   resolution (volume box, event model), which the identity determines. The thread count is
//!   not part of it: it changes only the order of float sums. Keys are [`KEY_LEN`] hex digits.

use std::path::Path;

use serde::Serialize;
use sha2::{Digest, Sha256};
use simulator::dataset::manifest::DatasetManifest;
use trainer::config::TrainConfig;
use trainer::presets::Scale;

use crate::error::BenchError;

/// Hex digits of cell keys and dataset folder names (64 bits).
pub const KEY_LEN: usize = 16;
/// Files larger than this (bytes) enter a folder's identity by size only.
pub const CONTENT_LIMIT: u64 = 64 << 20;
/// Bumped when the cell key's inputs change meaning, so that old results are not mistaken for
/// new ones.
pub const KEY_VERSION: u32 = 1;

/// SHA-256 of `bytes` as 64 lowercase hex digits.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What a cell key hashes.
#[derive(Serialize)]
struct KeyInputs<'a> {
    key_version: u32,
    preset: &'a str,
    scale: Scale,
    dataset: &'a str,
    config: &'a TrainConfig,
}

/// The key of a cell: `preset` at `scale` with `config` (seed and overrides applied) on the
/// dataset `dataset` (its identity). `config.threads` is ignored.
pub fn cell_key(preset: &str, scale: Scale, dataset: &str, config: &TrainConfig) -> String {
    let config = TrainConfig { threads: 0, ..config.clone() };
    let inputs = KeyInputs { key_version: KEY_VERSION, preset, scale, dataset, config: &config };
    let text = toml::to_string(&inputs).expect("a training configuration serialises to TOML");
    sha256_hex(text.as_bytes())[..KEY_LEN].to_string()
}

/// The identity of an existing dataset folder (see the module doc).
pub fn folder_identity(dir: &Path) -> Result<String, BenchError> {
    let manifest = DatasetManifest::read(dir).map_err(|e| {
        BenchError::results(&dir.join("dataset.toml"), format!("{e}; delete it or simulate the dataset again"))
    })?;
    if let Some(m) = manifest {
        return Ok(m.settings_hash);
    }
    let mut files = Vec::new();
    list_files(dir, dir, &mut files)?;
    files.sort();
    let mut h = Sha256::new();
    for rel in &files {
        let path = dir.join(rel);
        let read_err = |e: std::io::Error| BenchError::results(&path, format!("cannot read ({e}); check permissions"));
        let size = std::fs::metadata(&path).map_err(read_err)?.len();
        h.update(rel.as_bytes());
        h.update([0]);
        h.update(size.to_le_bytes());
        if size <= CONTENT_LIMIT {
            h.update(std::fs::read(&path).map_err(read_err)?);
        }
    }
    Ok(hex(&h.finalize()))
}

/// Relative paths (with `/`) of the non-hidden files under `dir`.
fn list_files(root: &Path, dir: &Path, out: &mut Vec<String>) -> Result<(), BenchError> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| BenchError::results(dir, format!("cannot list the dataset folder ({e}); check the path")))?;
    for entry in entries {
        let entry = entry.map_err(|e| BenchError::results(dir, format!("cannot list ({e})")))?;
        if entry.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        let path = entry.path();
        if path.is_dir() {
            list_files(root, &path, out)?;
        } else {
            let rel = path.strip_prefix(root).expect("below the root");
            out.push(rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use trainer::presets::preset;

    #[test]
    fn cell_keys_change_with_settings_but_not_with_threads() {
        let cfg = (preset("nerf").unwrap().build)(Scale::Cpu);
        let k = cell_key("nerf", Scale::Cpu, "d", &cfg);
        assert_eq!(k.len(), KEY_LEN);
        assert_eq!(k, cell_key("nerf", Scale::Cpu, "d", &TrainConfig { threads: 7, ..cfg.clone() }));
        for other in [
            cell_key("nerf", Scale::Cpu, "e", &cfg),
            cell_key("nerf", Scale::Paper, "d", &cfg),
            cell_key("nerf-sharp", Scale::Cpu, "d", &cfg),
            cell_key("nerf", Scale::Cpu, "d", &TrainConfig { seed: 1, ..cfg.clone() }),
            cell_key("nerf", Scale::Cpu, "d", &TrainConfig { iterations: 10, ..cfg.clone() }),
        ] {
            assert_ne!(k, other);
        }
    }

    #[test]
    fn folder_identity_follows_content_and_prefers_the_manifest() {
        let dir = std::env::temp_dir().join(format!("evbench-identity-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("images_1")).unwrap();
        std::fs::write(dir.join("poses_bounds.npy"), b"abc").unwrap();
        std::fs::write(dir.join("images_1/00.png"), b"x").unwrap();
        let a = folder_identity(&dir).unwrap();
        std::fs::write(dir.join(".hidden"), b"ignored").unwrap();
        assert_eq!(folder_identity(&dir).unwrap(), a);
        std::fs::write(dir.join("images_1/00.png"), b"y").unwrap();
        let b = folder_identity(&dir).unwrap();
        assert_ne!(a, b);
        let manifest = DatasetManifest { settings_hash: "feed".into(), ..DatasetManifest::example() };
        std::fs::write(dir.join("dataset.toml"), manifest.to_toml().unwrap()).unwrap();
        assert_eq!(folder_identity(&dir).unwrap(), "feed");
        // a damaged manifest is an error, not a fall-back to the file hash
        std::fs::write(dir.join("dataset.toml"), "settings_hash = \"feed\"\n").unwrap();
        assert!(folder_identity(&dir).unwrap_err().to_string().contains("dataset.toml"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
