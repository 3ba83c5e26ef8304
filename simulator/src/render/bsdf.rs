//! TODO(helper): Lambert + GGX metallic-roughness BSDF.
