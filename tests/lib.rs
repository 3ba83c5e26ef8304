//! Cross-crate and reference checks live in the test files beside this one:
//! `mitsuba_reference.rs` compares the path tracer with Mitsuba 3 on the scenes in `scenes/`.
