//! The .prisms file.
