//! Stage 2: repair.
