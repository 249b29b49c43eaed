//! bytes → an embedded material texture (USD's `auto` colour space) → `texture::ColorMap::load` (PNG, JPEG or TIFF through
//! the `image` crate, with the dimension and allocation limits): any input is a clean `Err` or
//! a map that keeps its invariants (one texel per pixel, each finite, and in [0, 1] for an
//! integer image, and a finite sample at any UV); a panic, abort or runaway allocation is a
//! bug.
#![no_main]

use glam::Vec2;
use libfuzzer_sys::fuzz_target;
use prismbake::texture::{
    ColorMap, ColorSpace, Sampler, TexWrap, TextureData, TextureRef, TextureSlot,
};
use std::path::Path;

/// Inside the image, on its edges, outside it, far off and not finite.
const UVS: [(f32, f32); 9] = [
    (0.5, 0.5),
    (0.0, 1.0),
    (1.0, 0.0),
    (0.13, 0.87),
    (-2.3, 3.7),
    (1.0e30, -1.0e30),
    (f32::NAN, 0.5),
    (0.5, f32::INFINITY),
    (f32::NEG_INFINITY, f32::NAN),
];

fuzz_target!(|data: &[u8]| {
    let tref = TextureRef {
        name: "fuzz".into(),
        data: TextureData::Embedded(data.to_vec()),
        sampler: Sampler::default(),
        tex_coord: 0,
        transform: Default::default(),
        // sRGB for an 8-bit colour image, raw for grey or 16-bit ones: both decoders' paths.
        color_space: ColorSpace::Auto,
        scale_bias: None,
    };
    let Ok(mut map) = ColorMap::load(Path::new("fuzz.glb"), &tref, TextureSlot::BaseColor) else {
        return;
    };
    assert!(map.width > 0 && map.height > 0);
    assert_eq!(map.texels.len(), map.width as usize * map.height as usize);
    // Integer images decode into [0, 1]; a float TIFF keeps its values, finite.
    let unit = map
        .texels
        .iter()
        .all(|t| t.min_element() >= 0.0 && t.max_element() <= 1.0);
    for t in &map.texels {
        assert!(t.is_finite(), "texel {t}");
    }
    let samplers = [
        Sampler::default(),
        Sampler {
            wrap: [TexWrap::Clamp, TexWrap::Mirror],
            nearest: false,
        },
        Sampler {
            wrap: [TexWrap::Mirror, TexWrap::Repeat],
            nearest: true,
        },
    ];
    for sampler in samplers {
        map.sampler = sampler;
        for (u, v) in UVS {
            let c = map.sample(Vec2::new(u, v));
            // Blends of the texels: finite, and in [0, 1] (up to rounding) where they are.
            assert!(c.is_finite(), "sample {c} at ({u}, {v})");
            assert!(
                !unit || (c.min_element() >= -1e-5 && c.max_element() <= 1.0 + 1e-5),
                "sample {c} at ({u}, {v})"
            );
        }
    }
});
