//! RMIP's per-prism traversal (Algorithm 1): project the ray interval's ends (§4.1), split the
//! projected curve at its turning points (§4.2), then pop texture-space bounds front to back,
//! cull each with a 3D box from the pyramid's displacement range, tighten it by projecting the
//! box interval's ends, split it at the midline of its longer side (§4.3), and march the
//! texels of bounds below the marching scale (§4.4).

use super::curve::Frame;
use super::Rmip;
use crate::bake::{Prism, M_LO_FLOOR};
use crate::canonical::{project_to_prism, PrismGeom};
use crate::seam::{PrismDisplacement, PrismStitch};
use crate::trace::prism_hit::{clip_to_surface_bounds, ray_prism_interval};
use crate::trace::Ray;
use glam::{DVec2, DVec3, Vec2, Vec3};

/// A refined hit may lie this far outside its triangle (barycentric units), as in PDM:
/// neighbours overlap by a hair instead of leaving a crack at their shared wall.
const EDGE_TOL: f32 = 1e-5;
/// Prism interval widening, relative to the longest base edge (as PDM's).
const INTERVAL_PAD: f32 = 1e-4;
/// Texture-space bounds grow by this many texels before a range query or a clip: the
/// projected endpoints carry Newton's residual (1e-6 of the prism), far below a texel.
const RECT_PAD: f64 = 1e-3;
/// Relative padding of the per-bound 3D boxes (fraction of the prism's longest edge).
const BOX_PAD: f64 = 1e-5;
/// Deepest subdivision before a bound is marched regardless of its size (each level halves
/// one side, so 48 levels reach a 2^-24 fraction of any prism).
const MAX_DEPTH: u32 = 48;
/// Stack capacity: the initial ≤ 5 pieces plus one per level.
const STACK: usize = MAX_DEPTH as usize + 8;
const REFINE_ITERS: u32 = 20;

/// A piece of the projected curve: ray parameters (relative to the prism entry) and their
/// texture-space points; monotone in x and y, so the rectangle of its ends bounds it.
#[derive(Clone, Copy, Debug, Default)]
struct Bound {
    t0: f64,
    t1: f64,
    p0: DVec2,
    p1: DVec2,
    depth: u32,
}

impl Bound {
    fn size(&self) -> f64 {
        let e = (self.p1 - self.p0).abs();
        e.x.max(e.y)
    }
    fn rect(&self) -> (DVec2, DVec2) {
        (
            self.p0.min(self.p1) - DVec2::splat(RECT_PAD),
            self.p0.max(self.p1) + DVec2::splat(RECT_PAD),
        )
    }
}

/// What a ray-prism pair needs: the texture-space traversal, or (UV-degenerate face, no
/// texture-space parametrisation) a plain march over the prism interval. Built once per
/// ray-prism pair on the stack, so the size difference is not boxed away.
#[allow(clippy::large_enum_variant)]
pub(super) enum Setup<'r, 'a> {
    Traverse(PrismTrace<'r, 'a>),
    Degenerate {
        local: Ray,
        te: f32,
        tx: f32,
        geom: PrismGeom,
    },
}

/// One ray in one prism.
pub(super) struct PrismTrace<'r, 'a> {
    rmip: &'r Rmip<'a>,
    frame: Frame,
    /// The prism relative to `V0`, in f32, for `canonical::project_to_prism`.
    geom: PrismGeom,
    /// Texel coordinates of the first UV corner (σ = texel coords − s0).
    s0: DVec2,
    /// Unit mean normal: `M·ĉ` bounds `|M|` from below (bake.rs).
    c_hat: DVec3,
    lambda_mid: f32,
    /// Prism entry (absolute ray parameter) and interval length.
    t_entry: f32,
    span: f64,
    scale: f64,
    ray: Ray,
    /// The stitched height where the prism has stitched seam edges (`seam`), else `None`.
    stitch: Option<(PrismDisplacement<'a>, &'a PrismStitch)>,
    pub steps: u32,
}

fn d2(v: Vec2) -> DVec2 {
    DVec2::new(v.x as f64, v.y as f64)
}

impl<'r, 'a> PrismTrace<'r, 'a> {
    /// Set up the traversal of `ray` in prism `p`, or `None` if the ray misses the prism.
    pub fn setup(rmip: &'r Rmip<'a>, ray: &Ray, p: &Prism, prism: u32) -> Option<Setup<'r, 'a>> {
        let t = &rmip.scene.table;
        let [i0, i1, i2] = p.tri.map(|i| i as usize);
        let origin = t.positions[i0];
        let v = [
            Vec3::ZERO,
            t.positions[i1] - origin,
            t.positions[i2] - origin,
        ];
        let n = [t.normals[i0], t.normals[i1], t.normals[i2]];
        let s = [t.uvs[i0], t.uvs[i1], t.uvs[i2]].map(|uv| rmip.scene.map.texel_coords(uv));
        let scale = v[1]
            .length()
            .max(v[2].length())
            .max((v[2] - v[1]).length())
            .max(f32::MIN_POSITIVE);
        let lo: [Vec3; 3] = std::array::from_fn(|i| v[i] + n[i] * p.lambda_lo);
        let hi: [Vec3; 3] = std::array::from_fn(|i| v[i] + n[i] * p.lambda_hi);
        let ro = ray.origin - origin;
        let pad = INTERVAL_PAD * scale;
        // Cut to where the surface can be first (a big λ range does not mean a long march,
        // and most candidate prisms are rejected here, before the walls).
        let reach = p.d_min.abs().max(p.d_max.abs()) + pad;
        let (t0, t1) = clip_to_surface_bounds(ro, ray.dir, ray.t_min, ray.t_max, &v, reach)?;
        let iv = ray_prism_interval(ro, ray.dir, t0, t1, &lo, &hi)?;
        let (te, tx) = ((iv.t_enter - pad).max(t0), (iv.t_exit + pad).min(t1));
        let geom = PrismGeom {
            v,
            n,
            uv: [Vec2::ZERO; 3],
        };
        let local = Ray { origin: ro, ..*ray };
        let srel = s.map(|x| x - s[0]);
        // Crease-strip prisms (zero-area base) are marched in `t` too: their texture-space
        // curve degenerates with the base, and the traversal lost rays in them that the other
        // methods find (docs/watertightness.md).
        let frame = if p.flags & crate::bake::PRISM_INSERTED != 0 {
            None
        } else {
            Frame::new(&v, &n, &srel, ro + ray.dir * te, ray.dir)
        };
        let Some(mut frame) = frame else {
            return Some(Setup::Degenerate {
                local,
                te,
                tx,
                geom,
            });
        };
        let slack = 0.01 * (p.lambda_hi - p.lambda_lo) as f64 + 1e-3 * scale as f64;
        frame.lambda_range = (p.lambda_lo as f64 - slack, p.lambda_hi as f64 + slack);
        let geom = PrismGeom { uv: srel, ..geom };
        Some(Setup::Traverse(PrismTrace {
            rmip,
            frame,
            geom,
            s0: d2(s[0]),
            c_hat: (n[0] + n[1] + n[2]).normalize_or_zero().as_dvec3(),
            lambda_mid: 0.5 * (p.lambda_lo + p.lambda_hi),
            t_entry: te,
            span: (tx - te) as f64,
            scale: scale as f64,
            ray: *ray,
            stitch: rmip
                .scene
                .stitch()
                .get(prism)
                .map(|s| (rmip.scene.prism_displacement(prism), s)),
            steps: 0,
        }))
    }

    #[inline]
    fn disp(&self, p: DVec2) -> f64 {
        if let Some((d, s)) = &self.stitch {
            let b = self.frame.bary(p);
            if s.in_band(b) {
                return d.at(b) as f64;
            }
        }
        let q = self.s0 + p;
        let h = sample_texel(&self.rmip.scene.map, q);
        self.rmip.scene.table.params.displacement(h) as f64
    }

    /// Newton-project the ray point at `t` (relative) onto the lines `P + λM`: its σ.
    fn project(&self, t: f64, guess: Vec3) -> Option<DVec2> {
        let x = self.frame.o + self.frame.d * t;
        let x = Vec3::new(x.x as f32, x.y as f32, x.z as f32);
        let starts = [guess, Vec3::splat(1.0 / 3.0), Vec3::X, Vec3::Y, Vec3::Z];
        let (lo, hi) = self.frame.lambda_range;
        starts
            .iter()
            .find_map(|&b| {
                // λ of x's projection on the line through the guess: in a zero-area crease
                // prism the prism's middle λ (≈ 0) is where the Jacobian is singular.
                let l = line_lambda(&self.geom, x, b).clamp(lo as f32, hi as f32);
                project_to_prism(&self.geom, x, b, l)
                    .or_else(|| project_to_prism(&self.geom, x, b, self.lambda_mid))
            })
            .map(|(b, _)| self.frame.sigma_of_bary(b))
    }

    /// The closest hit in this prism: absolute `t` and barycentrics.
    pub fn run(&mut self) -> Option<(f32, Vec3)> {
        let centre = Vec3::splat(1.0 / 3.0);
        let pe = self.project(0.0, centre)?;
        let px = self.project(self.span, self.frame.bary(pe))?;
        let (tp, ntp) = self.frame.turning_points(0.0, self.span);
        // Pieces between consecutive split points, pushed back to front.
        let mut pts = [(0.0, pe); 6];
        pts[1..=ntp].copy_from_slice(&tp[..ntp]);
        pts[ntp + 1] = (self.span, px);
        let mut stack = [Bound::default(); STACK];
        let mut sp = 0;
        for k in (0..=ntp).rev() {
            stack[sp] = Bound {
                t0: pts[k].0,
                t1: pts[k + 1].0,
                p0: pts[k].1,
                p1: pts[k + 1].1,
                depth: 0,
            };
            sp += 1;
        }
        let opts = &self.rmip.opts;
        let ms = opts.marching_scale as f64;
        while sp > 0 {
            sp -= 1;
            let mut bd = stack[sp];
            self.steps += 1;
            if bd.size() <= ms || bd.depth >= MAX_DEPTH || sp + 2 > STACK {
                if let Some(hit) = self.march(&bd) {
                    return Some(hit);
                }
                continue;
            }
            let (lo, hi) = bd.rect();
            let (mut hmin, mut hmax) = self.rmip.pyramid.sample_range(self.s0 + lo, self.s0 + hi);
            if let Some((_, s)) = &self.stitch {
                let corners = [lo, hi, DVec2::new(lo.x, hi.y), DVec2::new(hi.x, lo.y)];
                if corners.iter().any(|&c| s.in_band(self.frame.bary(c))) {
                    hmin = hmin.min(s.band_h.0);
                    hmax = hmax.max(s.band_h.1);
                }
            }
            let (dlo, dhi) = self.rmip.scene.table.params.displacement_range(hmin, hmax);
            let Some((ta, tb)) = self.box_interval(&bd, lo, hi, dlo as f64, dhi as f64) else {
                continue;
            };
            if opts.inversion {
                self.tighten(&mut bd, ta, tb);
                if bd.size() <= ms {
                    if let Some(hit) = self.march(&bd) {
                        return Some(hit);
                    }
                    continue;
                }
            }
            let Some((front, back)) = self.split(&bd) else {
                if let Some(hit) = self.march(&bd) {
                    return Some(hit);
                }
                continue;
            };
            stack[sp] = back;
            stack[sp + 1] = front;
            sp += 2;
        }
        None
    }

    /// Shrink `bd` to `[ta, tb]` by projecting the new ends (Fig. 5a), each kept inside the
    /// old rectangle (the piece is monotone, so a sub-piece stays in it).
    fn tighten(&self, bd: &mut Bound, ta: f64, tb: f64) {
        let eps = 1e-9 * self.span.max(1e-30);
        let (lo, hi) = (bd.p0.min(bd.p1), bd.p0.max(bd.p1));
        let lerp_b = |t: f64| {
            let w = ((t - bd.t0) / (bd.t1 - bd.t0).max(1e-300)).clamp(0.0, 1.0);
            self.frame.bary(bd.p0 + (bd.p1 - bd.p0) * w)
        };
        let (b_a, b_b) = (lerp_b(ta), lerp_b(tb));
        if ta > bd.t0 + eps {
            if let Some(p) = self.project(ta, b_a) {
                bd.t0 = ta;
                bd.p0 = p.clamp(lo, hi);
            }
        }
        if tb < bd.t1 - eps {
            if let Some(p) = self.project(tb, b_b) {
                bd.t1 = tb;
                bd.p1 = p.clamp(lo, hi);
            }
        }
    }

    /// Split at the midline of the longer side (Fig. 5c): the piece crosses it once; the
    /// crossing comes from the quadric, its `t` in closed form. Falls back to projecting the
    /// middle of the interval (Fig. 5b) if rounding hides the crossing.
    fn split(&self, bd: &Bound) -> Option<(Bound, Bound)> {
        let (lo, hi) = (bd.p0.min(bd.p1), bd.p0.max(bd.p1));
        let e = hi - lo;
        let (p_line, u, axis) = if e.x >= e.y {
            (DVec2::new(0.5 * (lo.x + hi.x), 0.0), DVec2::Y, 1)
        } else {
            (DVec2::new(0.0, 0.5 * (lo.y + hi.y)), DVec2::X, 0)
        };
        let tol = 1e-6 * (1.0 + e.max_element());
        let (pts, n) = self.frame.conic.on_line(p_line, u);
        let mut found = None;
        for p in &pts[..n] {
            let c = if axis == 1 { p.y } else { p.x };
            let (a, b) = if axis == 1 {
                (lo.y, hi.y)
            } else {
                (lo.x, hi.x)
            };
            if c < a - tol || c > b + tol {
                continue;
            }
            if let Some(t) = self.frame.t_on_branch(*p) {
                if t > bd.t0 && t < bd.t1 {
                    found = Some((t, p.clamp(lo, hi)));
                    break;
                }
            }
        }
        let (tm, pm) = match found {
            Some(x) => x,
            None => {
                let tm = 0.5 * (bd.t0 + bd.t1);
                let p = self.project(tm, self.frame.bary(0.5 * (bd.p0 + bd.p1)))?;
                (tm, p.clamp(lo, hi))
            }
        };
        let depth = bd.depth + 1;
        Some((
            Bound {
                t0: bd.t0,
                t1: tm,
                p0: bd.p0,
                p1: pm,
                depth,
            },
            Bound {
                t0: tm,
                t1: bd.t1,
                p0: pm,
                p1: bd.p1,
                depth,
            },
        ))
    }

    /// The ray interval inside the box that bounds the displaced surface over the bound's
    /// rectangle ∩ the base triangle, clipped to the bound's own interval.
    fn box_interval(
        &self,
        bd: &Bound,
        lo: DVec2,
        hi: DVec2,
        dlo: f64,
        dhi: f64,
    ) -> Option<(f64, f64)> {
        let (poly, n) = clip_triangle_to_rect(&self.frame.tri, lo, hi);
        if n < 3 {
            return None;
        }
        // |M| over the region: ≥ min M·ĉ (affine, so at a vertex), ≤ max |M| (convex).
        let (mut mmin, mut mmax) = (f64::INFINITY, 0.0f64);
        for p in &poly[..n] {
            let m = self.frame.dir(*p);
            mmin = mmin.min(m.dot(self.c_hat));
            mmax = mmax.max(m.length());
        }
        let mmin = mmin.max(M_LO_FLOOR as f64);
        let mmax = mmax.max(mmin);
        let l_lo = (dlo / mmin).min(dlo / mmax);
        let l_hi = (dhi / mmin).max(dhi / mmax);
        // (σ, λ) ↦ P + λM is affine in each: its extremes over polygon × [l_lo, l_hi] are at
        // the corners.
        let (mut bmin, mut bmax) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for p in &poly[..n] {
            let (x, m) = (self.frame.position(*p), self.frame.dir(*p));
            for l in [l_lo, l_hi] {
                let c = x + m * l;
                bmin = bmin.min(c);
                bmax = bmax.max(c);
            }
        }
        let pad = DVec3::splat(BOX_PAD * self.scale);
        let (bmin, bmax) = (bmin - pad, bmax + pad);
        let inv = self.frame.d.recip();
        let a = (bmin - self.frame.o) * inv;
        let b = (bmax - self.frame.o) * inv;
        // NaN (0 · ∞ on a slab plane) drops out of f64::min/max: that axis does not clip.
        let near = a.min(b);
        let far = a.max(b);
        let tn = near.x.max(near.y).max(near.z).max(bd.t0);
        let tf = far.x.min(far.y).min(far.z).min(bd.t1);
        (tn <= tf).then_some((tn, tf))
    }

    /// Texel marching (§4.4): walk the bilinear cells (corners at texel centres) the piece
    /// crosses, one cell edge at a time from the quadric, and refine the first sign change of
    /// the ray's height above the surface.
    fn march(&mut self, bd: &Bound) -> Option<(f32, Vec3)> {
        let f = &self.frame;
        let dir = (bd.p1 - bd.p0).signum();
        let dir = DVec2::new(
            if (bd.p1.x - bd.p0.x).abs() > 0.0 {
                dir.x
            } else {
                0.0
            },
            if (bd.p1.y - bd.p0.y).abs() > 0.0 {
                dir.y
            } else {
                0.0
            },
        );
        let (lo, hi) = bd.rect();
        // Index of the next cell edge (absolute texel coordinate k + 0.5) in each direction.
        let abs0 = self.s0 + bd.p0;
        let first = |x: f64, s: f64| -> i64 {
            if s > 0.0 {
                (x - 0.5).floor() as i64 + 1
            } else {
                (x - 0.5).ceil() as i64 - 1
            }
        };
        let mut kx = first(abs0.x, dir.x);
        let mut ky = first(abs0.y, dir.y);
        let cells = ((bd.p1 - bd.p0).abs().element_sum() as u32).saturating_add(4);
        let (mut t, mut p) = (bd.t0, bd.p0);
        let mut g = f.ray_height(p, t) - self.disp(p);
        for _ in 0..cells.saturating_mul(2) {
            // Crossing with the next vertical and horizontal cell edges; the earlier wins.
            let mut best: Option<(f64, DVec2, u8)> = None;
            for axis in 0..2u8 {
                let s = if axis == 0 { dir.x } else { dir.y };
                if s == 0.0 {
                    continue;
                }
                let k = if axis == 0 { kx } else { ky };
                let line = k as f64 + 0.5 - if axis == 0 { self.s0.x } else { self.s0.y };
                let (p_line, u) = if axis == 0 {
                    (DVec2::new(line, 0.0), DVec2::Y)
                } else {
                    (DVec2::new(0.0, line), DVec2::X)
                };
                let within = if axis == 0 {
                    line >= lo.x && line <= hi.x
                } else {
                    line >= lo.y && line <= hi.y
                };
                if !within {
                    continue;
                }
                let (pts, n) = f.conic.on_line(p_line, u);
                for q in &pts[..n] {
                    let other_ok = if axis == 0 {
                        q.y >= lo.y && q.y <= hi.y
                    } else {
                        q.x >= lo.x && q.x <= hi.x
                    };
                    if !other_ok {
                        continue;
                    }
                    if let Some(tq) = f.t_on_branch(*q) {
                        if tq >= t && tq <= bd.t1 && best.is_none_or(|b| tq < b.0) {
                            best = Some((tq, *q, axis));
                        }
                    }
                }
            }
            let (tn, pn) = match best {
                Some((tq, q, axis)) => {
                    if axis == 0 {
                        kx += dir.x as i64;
                    } else {
                        ky += dir.y as i64;
                    }
                    (tq, q)
                }
                None => (bd.t1, bd.p1),
            };
            self.steps += 1;
            let gn = f.ray_height(pn, tn) - self.disp(pn);
            if (g > 0.0) != (gn > 0.0) {
                if let Some(hit) = self.refine(t, tn, p, pn) {
                    return Some(hit);
                }
            }
            if best.is_none() {
                break;
            }
            (t, p, g) = (tn, pn, gn);
        }
        None
    }

    /// Illinois regula falsi on the ray's height above the canonical surface between two
    /// curve points of opposite sign; each evaluation projects the ray point by Newton.
    fn refine(&self, mut t0: f64, mut t1: f64, p0: DVec2, p1: DVec2) -> Option<(f32, Vec3)> {
        // Confirm the bracket on the Newton-projected surface: the quadric's points carry no
        // λ check beyond the shell's, and a false bracket must not become a hit.
        let eval = |t: f64, guess: DVec2| -> Option<(f64, DVec2)> {
            let q = self.project(t, self.frame.bary(guess))?;
            Some((self.frame.ray_height(q, t) - self.disp(q), q))
        };
        let ((e0, mut q0), (e1, mut q1)) = (eval(t0, p0)?, eval(t1, p1)?);
        if (e0 > 0.0) == (e1 > 0.0) {
            return None;
        }
        let (mut g0, mut g1) = (e0, e1);
        let tol_g = 1e-6 * self.scale;
        let tol_t = 1e-7 * (self.span + self.scale);
        let mut side = 0;
        for _ in 0..REFINE_ITERS {
            if g0.abs() <= tol_g || g1.abs() <= tol_g || (t1 - t0).abs() <= tol_t {
                break;
            }
            let t = (t0 * g1 - t1 * g0) / (g1 - g0);
            let w = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
            let Some(q) = self.project(t, self.frame.bary(q0 + (q1 - q0) * w)) else {
                break;
            };
            let g = self.frame.ray_height(q, t) - self.disp(q);
            if (g > 0.0) == (g1 > 0.0) {
                (t1, g1, q1) = (t, g, q);
                if side == -1 {
                    g0 *= 0.5;
                }
                side = -1;
            } else {
                (t0, g0, q0) = (t, g, q);
                if side == 1 {
                    g1 *= 0.5;
                }
                side = 1;
            }
        }
        let (t, q) = if g0.abs() <= g1.abs() {
            (t0, q0)
        } else {
            (t1, q1)
        };
        let b = self.frame.bary(q);
        let t_abs = self.t_entry + t as f32;
        let ok = b.min_element() >= -EDGE_TOL && t_abs >= self.ray.t_min && t_abs <= self.ray.t_max;
        ok.then_some((t_abs, b))
    }
}

/// Bilinear sample at continuous texel coordinates (texel `i` centred at `i + 0.5`), the
/// convention of `HeightMap::sample`, without the uv round trip.
#[inline]
pub fn sample_texel(map: &crate::heightmap::HeightMap, q: DVec2) -> f32 {
    let p = q - DVec2::splat(0.5);
    let (fx, fy) = (p.x.floor(), p.y.floor());
    let (tx, ty) = ((p.x - fx) as f32, (p.y - fy) as f32);
    let (x, y) = (fx as i64, fy as i64);
    let a = map.texel(x, y);
    let b = map.texel(x + 1, y);
    let c = map.texel(x, y + 1);
    let d = map.texel(x + 1, y + 1);
    let top = a + (b - a) * tx;
    let bottom = c + (d - c) * tx;
    top + (bottom - top) * ty
}

/// Sutherland–Hodgman: the triangle clipped to an axis-aligned rectangle (≤ 7 vertices).
fn clip_triangle_to_rect(tri: &[DVec2; 3], lo: DVec2, hi: DVec2) -> ([DVec2; 8], usize) {
    let mut a = [DVec2::ZERO; 8];
    let mut b = [DVec2::ZERO; 8];
    a[..3].copy_from_slice(tri);
    let mut n = 3;
    for plane in 0..4 {
        // inside(p) ≥ 0
        let dist = |p: DVec2| match plane {
            0 => p.x - lo.x,
            1 => hi.x - p.x,
            2 => p.y - lo.y,
            _ => hi.y - p.y,
        };
        let mut m = 0;
        for i in 0..n {
            let (p, q) = (a[i], a[(i + 1) % n]);
            let (dp, dq) = (dist(p), dist(q));
            if dp >= 0.0 {
                b[m] = p;
                m += 1;
            }
            if (dp >= 0.0) != (dq >= 0.0) && m < 8 {
                b[m] = p + (q - p) * (dp / (dp - dq));
                m += 1;
            }
        }
        n = m.min(8);
        a = b;
        if n == 0 {
            break;
        }
    }
    (a, n)
}

/// `λ` of the point on the line `P(b) + λ m(b)` nearest to `x`: a Newton start for
/// `project_to_prism` that is right on the line of the guess `b`.
fn line_lambda(g: &PrismGeom, x: Vec3, b: Vec3) -> f32 {
    let m = g.normal_dir(b);
    (x - g.position(b)).dot(m) / m.length_squared().max(1e-30)
}

/// Fallback for prisms without a texture-space parametrisation (UV-degenerate faces):
/// march the prism interval in `t` at half a texel (or 1/16 of the thickness), sign changes
/// refined on the canonical surface as above.
#[allow(clippy::too_many_arguments)]
pub(super) fn march_degenerate(
    rmip: &Rmip,
    p: &Prism,
    prism: u32,
    local: &Ray,
    te: f32,
    tx: f32,
    geom: &PrismGeom,
    steps: &mut u32,
) -> Option<(f32, Vec3)> {
    let disp = rmip.scene.prism_displacement(prism);
    let (m0, m1) = (te, tx);
    let thick = (p.lambda_hi - p.lambda_lo).abs().max(1e-12);
    let dt = if p.texel_world > 0.0 {
        0.5 * p.texel_world
    } else {
        thick / 16.0
    }
    .max((m1 - m0) / 4096.0);
    let g_at = |t: f32, guess: Vec3| -> Option<(f32, Vec3)> {
        let x = local.origin + local.dir * t;
        let l0 = line_lambda(geom, x, guess).clamp(p.lambda_lo - thick, p.lambda_hi + thick);
        let (b, l) = project_to_prism(geom, x, guess, l0)
            .or_else(|| project_to_prism(geom, x, guess, 0.5 * (p.lambda_lo + p.lambda_hi)))?;
        let m = geom.normal_dir(b).length();
        Some((l * m - disp.at(b), b))
    };
    let mut prev: Option<(f32, f32, Vec3)> = None;
    let mut t = m0;
    loop {
        *steps += 1;
        let guess = prev.map_or(Vec3::splat(1.0 / 3.0), |x| x.2);
        if let Some((g, b)) = g_at(t, guess) {
            if let Some((tp, gp, bp)) = prev {
                if (gp > 0.0) != (g > 0.0) {
                    // Bisection: few such prisms, robustness over speed.
                    let (mut a, mut c, mut ga, mut bb) = (tp, t, gp, bp);
                    for _ in 0..30 {
                        let mid = 0.5 * (a + c);
                        let Some((gm, bm)) = g_at(mid, bb) else { break };
                        if (gm > 0.0) == (ga > 0.0) {
                            (a, ga) = (mid, gm);
                        } else {
                            c = mid;
                        }
                        bb = bm;
                    }
                    let tm = 0.5 * (a + c);
                    if bb.min_element() >= -EDGE_TOL && tm >= local.t_min && tm <= local.t_max {
                        return Some((tm, bb));
                    }
                }
            }
            prev = Some((t, g, b));
        }
        if t >= m1 {
            return None;
        }
        t = (t + dt).min(m1);
    }
}
