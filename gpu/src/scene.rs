//! A `prismbake::accel::Scene` on the GPU: prism records, base vertices, a BVH2 over the same
//! padded prism boxes the CPU uses (`accel::prism_aabbs`), and the height map in an r32uint
//! texture, two texels a word where that keeps them exact (`layout::encode_height_map`), read
//! with `textureLoad` and the CPU's bilinear weights and wrap, so that sampling is bit-for-bit
//! the CPU's rather than a texture unit's 8-bit-fraction filtering. A texture, not a storage
//! buffer: the map is bounded by the device's largest texture side (an 8192² f32 map on any
//! adapter), not by one storage binding (128 MiB on lavapipe and WebGPU's defaults).
//!
//! The CPU scene holds a CWBVH (8-wide, best on CPUs); the GPU gets a binary obvhs BVH2 built
//! from the same boxes, flattened into `GpuBvhNode`s (obvhs's `small_bvh2_node` layout; the
//! feature itself is not enabled, so the CPU's BVH2 is unchanged) with leaves pointing into a
//! prism index list.
//!
//! Next to UV seams the scene traces the stitched height (`prismbake::seam`): when the
//! scene's seam mode is `Stitch`, each stitched prism's record goes up as a `GpuPrismStitch`
//! and its `GpuPrism::stitch` indexes it; every other prism (all of them under `Open`) carries
//! `NO_STITCH` and the shaders evaluate the raw `D(uv(b))`.

use crate::context::GpuContext;
use crate::layout::{
    encode_height_map, wrap_code, EncodedMap, GpuBvhNode, GpuMaterial, GpuPrism, GpuPrismStitch,
    GpuSceneParams, GpuVertex, MapEncoding, NO_STITCH,
};
use crate::GpuError;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::BvhBuildParams;
use prismbake::accel::{prism_aabbs, Scene};
use prismbake::seam::{SeamMode, StitchField};
use std::time::Duration;
use wgpu::util::DeviceExt;

/// The flattened hierarchy: nodes (root first) and the leaf-to-prism index list.
pub struct FlatBvh {
    pub nodes: Vec<GpuBvhNode>,
    pub prim_indices: Vec<u32>,
}

/// Build a BVH2 over the scene's prism boxes (obvhs `medium_build`, as the CPU, but one prism
/// per leaf) and flatten it.
pub fn flatten_bvh(scene: &Scene) -> FlatBvh {
    let aabbs = prism_aabbs(&scene.table);
    if aabbs.is_empty() {
        return FlatBvh {
            nodes: vec![],
            prim_indices: vec![],
        };
    }
    let mut build_time = Duration::default();
    // One prism per leaf: the kernel tests a leaf's prisms in a loop that runs, in lock-step
    // implementations, as long as any lane's leaf has prisms left, and each pass is a whole
    // prism test (lavapipe, sphere 512² AOV frame: 0.66-0.73 s with up to 8 per leaf, 0.54-0.61
    // s with one).
    let params = BvhBuildParams {
        max_prims_per_leaf: 1,
        ..BvhBuildParams::medium_build()
    };
    let bvh = build_bvh2(&aabbs, params, &mut build_time);
    let nodes = bvh
        .nodes
        .iter()
        .map(|n| GpuBvhNode {
            min: n.aabb.min.to_array(),
            prim_count: n.prim_count,
            max: n.aabb.max.to_array(),
            first_index: n.first_index,
        })
        .collect();
    FlatBvh {
        nodes,
        prim_indices: bvh.primitive_indices.clone(),
    }
}

pub struct GpuScene {
    pub(crate) group: wgpu::BindGroup,
    /// Group 2 of the AOV kernels: the materials' records and texels their traversal reads for
    /// the alpha (`cut_out`); one opaque material until then.
    pub(crate) cut_group: wgpu::BindGroup,
    pub(crate) params: GpuSceneParams,
    stitched_prisms: u32,
    bytes: u64,
    method_bytes: u64,
    buffers: MapBuffers,
}

/// The buffers a new height map rewrites (`GpuScene::update_map`).
struct MapBuffers {
    params: wgpu::Buffer,
    prisms: wgpu::Buffer,
    map: wgpu::Texture,
    stitches: wgpu::Buffer,
}

/// What of a scene depends on its height map: the prism records (bounds, stitch references),
/// the stitch records (one zeroed record where there are none: a binding holds one at least)
/// and the encoded map.
struct MapArrays<'a> {
    prisms: Vec<GpuPrism>,
    stitches: Vec<GpuPrismStitch>,
    stitched_prisms: u32,
    encoded: EncodedMap<'a>,
}

impl<'a> MapArrays<'a> {
    fn new(scene: &'a Scene) -> Self {
        let empty = StitchField::empty();
        let stitch = match scene.seam_mode() {
            SeamMode::Stitch => scene.stitch(),
            SeamMode::Open => &empty,
        };
        let prisms: Vec<GpuPrism> = scene
            .table
            .prisms
            .iter()
            .enumerate()
            .map(|(i, p)| GpuPrism {
                tri: p.tri,
                flags: p.flags,
                d_min: p.d_min,
                d_max: p.d_max,
                lambda_lo: p.lambda_lo,
                lambda_hi: p.lambda_hi,
                texel_world: p.texel_world,
                stitch: stitch.record_index(i as u32).unwrap_or(NO_STITCH),
            })
            .collect();
        let mut stitches: Vec<GpuPrismStitch> =
            stitch.records().iter().map(GpuPrismStitch::from).collect();
        let stitched_prisms = stitches.len() as u32;
        if stitches.is_empty() {
            // Zero-sized bindings are invalid, and a runtime array binds one element at least.
            stitches.push(GpuPrismStitch::default());
        }
        MapArrays {
            prisms,
            stitches,
            stitched_prisms,
            encoded: encode_height_map(&scene.map.data, scene.map.width),
        }
    }
}

/// The scene constants of `scene` with `node_count` BVH nodes and its map stored as `encoding`.
fn scene_params(scene: &Scene, node_count: u32, encoding: MapEncoding) -> GpuSceneParams {
    let map = &scene.map;
    GpuSceneParams {
        map_width: map.width,
        map_height: map.height,
        wrap: wrap_code(map.wrap),
        node_count,
        disp_scale: scene.table.params.scale,
        disp_midlevel: scene.table.params.midlevel,
        prism_count: scene.table.prisms.len() as u32,
        map_encoding: encoding as u32,
    }
}

impl GpuScene {
    /// Upload a scene. Fails with `GpuError::TooLarge` if one array exceeds the device's
    /// storage-binding limit (128 MiB on WebGPU defaults: ~3.3 M prisms), and with
    /// `GpuError::TextureTooLarge` if the map's texture has a side over the device's largest
    /// (8192 on WebGPU's defaults: an 8192² f32 map, or 16384 × 8192 packed two a word).
    /// Let the AOV kernels cut surfaces away by the materials' alpha: `records` (the alpha of
    /// each, `beauty::alpha_records`) and the texels their textures read become the cut-out
    /// group. Fails with `GpuError::TooLarge` where the texels exceed one storage binding.
    pub fn cut_out(
        &mut self,
        ctx: &GpuContext,
        records: &[GpuMaterial],
        texels: &[f32],
    ) -> Result<(), GpuError> {
        let (bytes, limit) = (
            std::mem::size_of_val(texels) as u64,
            ctx.max_binding_bytes(),
        );
        if bytes > limit {
            return Err(GpuError::TooLarge {
                what: "alpha texture texels",
                bytes,
                limit,
                fix: "downsample the alpha textures, or pass --no-alpha",
            });
        }
        self.cut_group = cut_group(ctx, records, texels);
        ctx.check()
    }

    pub fn upload(ctx: &GpuContext, scene: &Scene) -> Result<GpuScene, GpuError> {
        let table = &scene.table;
        let MapArrays {
            prisms,
            stitches,
            stitched_prisms,
            encoded,
        } = MapArrays::new(scene);
        let vertices: Vec<GpuVertex> = (0..table.positions.len())
            .map(|i| GpuVertex {
                position: table.positions[i].to_array(),
                u: table.uvs[i].x,
                normal: table.normals[i].to_array(),
                v: table.uvs[i].y,
            })
            .collect();
        let bvh = flatten_bvh(scene);
        let params = scene_params(scene, bvh.nodes.len() as u32, encoded.encoding);
        let limit = ctx.max_binding_bytes();
        let mut bytes = 0u64;
        let mut storage = |what: &'static str, data: &[u8]| -> Result<wgpu::Buffer, GpuError> {
            if data.len() as u64 > limit {
                return Err(GpuError::TooLarge {
                    what,
                    bytes: data.len() as u64,
                    limit,
                    fix: "use --device auto or cpu (the CPU renderer has no such limit), or a smaller asset",
                });
            }
            bytes += data.len() as u64;
            // Zero-sized bindings are invalid: an empty array gets one zeroed element.
            let padded;
            let contents = if data.is_empty() {
                padded = [0u8; 32];
                &padded[..]
            } else {
                data
            };
            Ok(ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(what),
                    contents,
                    // Writable for `update_map`.
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                }))
        };
        let prism_buf = storage("prisms", bytemuck::cast_slice(&prisms))?;
        let vertex_buf = storage("vertices", bytemuck::cast_slice(&vertices))?;
        let node_buf = storage("BVH nodes", bytemuck::cast_slice(&bvh.nodes))?;
        let index_buf = storage("BVH prism indices", bytemuck::cast_slice(&bvh.prim_indices))?;
        check_map_fits(ctx, &encoded)?;
        let map_tex = map_texture(ctx, &encoded);
        let map_view = map_tex.create_view(&Default::default());
        let stitch_buf = storage("seam stitch records", bytemuck::cast_slice(&stitches))?;
        let param_buf = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("scene params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scene"),
            layout: &ctx.scene_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: param_buf.as_entire_binding(),
                }, // scene
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: prism_buf.as_entire_binding(),
                }, // prisms
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: vertex_buf.as_entire_binding(),
                }, // vertices
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: node_buf.as_entire_binding(),
                }, // nodes
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: index_buf.as_entire_binding(),
                }, // prim_indices
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(&map_view),
                }, // height_map
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: stitch_buf.as_entire_binding(),
                }, // stitches
            ],
        });
        bytes += std::mem::size_of_val(&encoded.words[..]) as u64;
        let method_bytes = (std::mem::size_of_val(&bvh.nodes[..])
            + std::mem::size_of_val(&bvh.prim_indices[..])
            + std::mem::size_of_val(&prisms[..])) as u64;
        // A buffer the driver refused (out of memory) shows here, not as a panic.
        ctx.check()?;
        Ok(GpuScene {
            group,
            cut_group: cut_group(ctx, &[GpuMaterial::default()], &[0.0]),
            params,
            stitched_prisms,
            bytes,
            method_bytes,
            buffers: MapBuffers {
                params: param_buf,
                prisms: prism_buf,
                map: map_tex,
                stitches: stitch_buf,
            },
        })
    }

    /// Rewrite in place what a new height map changes (`watch`): the prism records (their
    /// re-baked bounds and stitch references), the stitch records, the map and the scene
    /// constants, keeping the vertices and the BVH, whose boxes still hold the prisms when the
    /// re-bake kept the CPU's BVH (`RebakeStats::bvh_rebuild_needed` false). Returns `false`,
    /// writing nothing, where an array's size changed (another map size or encoding, another
    /// number of stitched prisms): the caller uploads the scene anew.
    pub fn update_map(&mut self, ctx: &GpuContext, scene: &Scene) -> bool {
        let arrays = MapArrays::new(scene);
        // `upload`'s sizes: the data's, 32 bytes for an empty array.
        let size = |b: &wgpu::Buffer, data: &[u8]| {
            b.size()
                == if data.is_empty() {
                    32
                } else {
                    data.len() as u64
                }
        };
        let b = &self.buffers;
        if !size(&b.prisms, bytemuck::cast_slice(&arrays.prisms))
            || !size(&b.stitches, bytemuck::cast_slice(&arrays.stitches))
            || b.map.size() != map_extent(&arrays.encoded)
        {
            return false;
        }
        let params = scene_params(scene, self.params.node_count, arrays.encoded.encoding);
        let q = &ctx.queue;
        q.write_buffer(&b.prisms, 0, bytemuck::cast_slice(&arrays.prisms));
        q.write_buffer(&b.stitches, 0, bytemuck::cast_slice(&arrays.stitches));
        write_map(ctx, &b.map, &arrays.encoded);
        q.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
        self.params = params;
        self.stitched_prisms = arrays.stitched_prisms;
        true
    }

    /// How the height map is stored (`MapEncoding`).
    pub fn map_encoding(&self) -> MapEncoding {
        match self.params.map_encoding {
            1 => MapEncoding::Unorm16,
            2 => MapEncoding::F16,
            _ => MapEncoding::F32,
        }
    }

    pub fn prism_count(&self) -> u32 {
        self.params.prism_count
    }

    /// Prisms uploaded with a stitch record (0 under `SeamMode::Open`).
    pub fn stitched_prisms(&self) -> u32 {
        self.stitched_prisms
    }

    /// Bytes uploaded (prisms, vertices, BVH, map, stitch records).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Bytes of what PDM holds beyond mesh and map (BVH nodes, indices, prism records): the
    /// GPU counterpart of `Intersector::memory_bytes`.
    pub fn method_bytes(&self) -> u64 {
        self.method_bytes
    }
}

/// The texture of an encoded map: `row_words` × rows.
fn map_extent(e: &EncodedMap) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width: e.row_words.max(1),
        height: e.rows(),
        depth_or_array_layers: 1,
    }
}

/// Whether the map's texture fits the device's largest texture side.
fn check_map_fits(ctx: &GpuContext, e: &EncodedMap) -> Result<(), GpuError> {
    let size = map_extent(e);
    ctx.check_texture_side(
        match e.encoding {
            MapEncoding::F32 => "height map (one f32 texel a texel of its texture)",
            _ => "height map (two 16-bit texels a texel of its texture)",
        },
        size.width,
        size.height,
        "use --device auto or cpu (the CPU renderer has no such limit), or a smaller map",
    )
}

/// The map's r32uint texture, filled (`check_map_fits` first).
pub fn map_texture(ctx: &GpuContext, e: &EncodedMap) -> wgpu::Texture {
    let size = map_extent(e);
    let texture = ctx.load_texture(
        "height map",
        wgpu::TextureFormat::R32Uint,
        size.width,
        size.height,
    );
    write_map(ctx, &texture, e);
    texture
}

/// Write an encoded map into its texture (of `map_extent`); an empty map leaves it zero.
fn write_map(ctx: &GpuContext, texture: &wgpu::Texture, e: &EncodedMap) {
    if e.words.is_empty() {
        return;
    }
    let size = map_extent(e);
    ctx.write_texture_rows(
        texture,
        0,
        size.height,
        bytemuck::cast_slice(&e.words),
        0,
        4 * size.width,
    );
}

/// The AOV kernels' group 2 (`GpuContext::cut_layout`): `records` as `materials`, `texels` as
/// `texture_texels` (neither empty: a binding holds one element at least).
fn cut_group(ctx: &GpuContext, records: &[GpuMaterial], texels: &[f32]) -> wgpu::BindGroup {
    let buffer = |label, contents: &[u8]| {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
    };
    let texels = buffer("alpha texels", bytemuck::cast_slice(texels));
    let materials = buffer("alpha materials", bytemuck::cast_slice(records));
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("materials' alpha"),
        layout: &ctx.cut_layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 1,
                resource: texels.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: materials.as_entire_binding(),
            },
        ],
    })
}
