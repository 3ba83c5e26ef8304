//! `--shard i/n`: a deterministic part of a matrix, so that array jobs (Slurm, Kubernetes) or
//! several machines can split it. The cells are taken in key order (the plan's order, the same
//! on every machine) and shard `i` of `n` gets the cells at positions `p` with `p % n == i - 1`.
//! Positions count every cell, finished or not, so the split never moves as work completes;
//! the union of shards 1..=n is the whole matrix and no two shards share a cell.

use std::fmt;
use std::str::FromStr;

/// Shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which part, 1..=count.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Shard {
    /// The whole matrix (shard 1 of 1).
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Whether the cell at `position` (in key order) is in this shard.
    pub fn contains(&self, position: usize) -> bool {
        position % self.count == self.index - 1
    }
}

impl Default for Shard {
    fn default() -> Shard {
        Shard::ALL
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// Parses `i/n` with `1 <= i <= n`.
    fn from_str(s: &str) -> Result<Shard, String> {
        let parsed = s.split_once('/').and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)));
        match parsed {
            Some((index, count)) if count >= 1 && (1..=count).contains(&index) => Ok(Shard { index, count }),
            _ => Err(format!(
                "`{s}`: expected i/n with 1 <= i <= n, e.g. 1/4 (for a Slurm array: --shard $((SLURM_ARRAY_TASK_ID+1))/$SLURM_ARRAY_TASK_COUNT)"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_i_of_n_and_refuses_the_rest() {
        assert_eq!("2/3".parse::<Shard>(), Ok(Shard { index: 2, count: 3 }));
        assert_eq!("1/1".parse::<Shard>(), Ok(Shard::ALL));
        for bad in ["0/2", "3/2", "1/0", "2", "a/b", "1/2/3", ""] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.contains("i/n"), "{bad}: {e}");
        }
    }

    #[test]
    fn shards_partition_the_positions() {
        for n in 1..5 {
            for p in 0..17 {
                let owners = (1..=n).filter(|&i| Shard { index: i, count: n }.contains(p)).count();
                assert_eq!(owners, 1, "position {p} of {n} shards");
            }
        }
    }
}
