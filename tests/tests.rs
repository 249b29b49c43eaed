//! End-to-end tests of the `prismbake` binary on real files: one module per topic.

mod util;

mod bad_input;
mod bake;
mod beauty;
mod bench;
mod denoise;
mod gpu;
mod render;
mod seams;
mod validate;
