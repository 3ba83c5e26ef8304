//! Benchmark: metrics, run matrix, sweeps and tables (to come; see issue tracker).
