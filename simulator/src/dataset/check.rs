//! The dataset schema check (to be written).
