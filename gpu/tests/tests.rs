//! prismbake-gpu tests, one module per topic. They need a wgpu adapter: on a machine without a
//! GPU, Mesa's lavapipe (Debian `mesa-vulkan-drivers`) is enough, and its absence is a test
//! failure, not a skip — CI must prove the GPU path, not silently pass without it.

mod util;

mod beauty;
mod env;
mod errors;
mod heightmap;
mod layout;
mod parity;
mod prism_hit;
mod rng;
mod seams;
mod texture;
