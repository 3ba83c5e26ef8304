//! Cross-crate and reference checks; see the files beside this one.
