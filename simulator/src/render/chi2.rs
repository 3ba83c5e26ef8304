//! TODO(helper): chi-square test for direction samplers.
