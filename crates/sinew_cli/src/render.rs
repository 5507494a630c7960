//! `render`: a small software rasteriser (z-buffer, Lambert shading) that
//! draws a scene's bones, muscles and skin at a chosen frame into a PNG —
//! no GPU, no window, so it runs in CI and over SSH.

use crate::commands::load_solver;
use sinew_core::Solver;
use sinew_core::analysis::skinned_surface;
use sinew_core::closest::TargetSource;
use sinew_core::glam::{Mat3, Vec2, Vec3};
use std::error::Error;
use std::path::Path;
use std::process::ExitCode;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// Where the camera looks from.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum View {
    /// From +Z: the front of a Y-up body facing +Z (the imported anatomy).
    Front,
    /// From +X: the body's left side.
    Side,
    /// From −X: the body's right side.
    OtherSide,
    /// From −Z: the back.
    Back,
}

impl View {
    fn direction(self) -> Vec3 {
        match self {
            Self::Front => Vec3::Z,
            Self::Side => Vec3::X,
            Self::OtherSide => -Vec3::X,
            Self::Back => -Vec3::Z,
        }
    }
}

/// How a skin (a body bound to the skeleton) is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SkinDraw {
    /// The simulated skin.
    Simulated,
    /// The character's plain skinning (linear blend, no simulation).
    Skinned,
    /// The simulated skin coloured by how far it stands out of the plain
    /// skinned surface: red outward, blue inward, white at 0, full colour
    /// at ±10 mm.
    Displacement,
    /// Side by side: plain skinning on the left, the simulated skin
    /// coloured by displacement on the right.
    Compare,
    /// Left out (the muscles under it show).
    Hidden,
}

/// What `render` draws and how it frames it.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Camera direction.
    pub view: View,
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Draw the bones.
    pub bones: bool,
    /// How skins are drawn.
    pub skin: SkinDraw,
    /// Frame this muscle, skin or bone instead of every muscle.
    pub focus: Option<String>,
}

/// One coloured triangle in world space.
struct Tri {
    p: [Vec3; 3],
    color: [f32; 3],
}

/// Skin colour of the simulated and the plainly skinned skin.
const SKIN_COLOR: [f32; 3] = [0.86, 0.68, 0.58];

/// Outward displacement (m) at which [`SkinDraw::Displacement`] reaches its
/// full colour.
const DISPLACEMENT_SCALE: f32 = 0.010;

/// White at 0, red at `+1`, blue at `−1` (clamped).
fn diverging(t: f32) -> [f32; 3] {
    let t = t.clamp(-1.0, 1.0);
    if t >= 0.0 {
        [1.0, 1.0 - 0.8 * t, 1.0 - 0.85 * t]
    } else {
        [1.0 + 0.85 * t, 1.0 + 0.55 * t, 1.0]
    }
}

/// The triangles of a skin drawn as `skin` says.
fn skin_triangles(
    solver: &Solver,
    m: &sinew_core::muscle::Muscle,
    skin: SkinDraw,
    tris: &mut Vec<Tri>,
) {
    let pose = |b: usize| solver.bones()[b].transform;
    let skinned = match skin {
        SkinDraw::Hidden => return,
        SkinDraw::Simulated => Vec::new(),
        _ => skinned_surface(m, &pose),
    };
    for tri in &m.mesh.triangles {
        let v = tri.map(|i| i as usize);
        let (p, color) = match skin {
            SkinDraw::Hidden => unreachable!("left out above"),
            SkinDraw::Simulated => (v.map(|i| m.x[i]), SKIN_COLOR),
            SkinDraw::Skinned => (v.map(|i| skinned[i].0), SKIN_COLOR),
            SkinDraw::Displacement | SkinDraw::Compare => {
                let outward = v
                    .iter()
                    .map(|&i| (m.x[i] - skinned[i].0).dot(skinned[i].1) / m.length_unit)
                    .sum::<f32>()
                    / 3.0;
                (v.map(|i| m.x[i]), diverging(outward / DISPLACEMENT_SCALE))
            }
        };
        tris.push(Tri { p, color });
    }
}

fn collect(solver: &Solver, bones: bool, skin: SkinDraw) -> Vec<Tri> {
    let mut tris = Vec::new();
    if bones {
        for t in solver.targets() {
            if !matches!(t.source, TargetSource::Bone(_)) {
                continue;
            }
            let world: Vec<Vec3> = t
                .positions()
                .iter()
                .map(|&p| t.transform.transform_point3(p))
                .collect();
            for tri in t.triangles() {
                tris.push(Tri {
                    p: tri.map(|i| world[i as usize]),
                    color: [0.86, 0.83, 0.74],
                });
            }
        }
    }
    for m in solver.muscles() {
        if m.is_skin() {
            skin_triangles(solver, m, skin, &mut tris);
            continue;
        }
        // Relaxed muscle: dusty red; active: bright red.
        let a = m.params.activation.clamp(0.0, 1.0);
        let color = [0.55 + 0.4 * a, 0.22 - 0.1 * a, 0.2 - 0.08 * a];
        for tri in &m.mesh.triangles {
            tris.push(Tri {
                p: tri.map(|i| m.x[i as usize]),
                color,
            });
        }
    }
    tris
}

/// The points the camera frames: those of the body named `focus`, else
/// every muscle's (bones may extend far beyond them), else everything drawn.
fn framed_points(solver: &Solver, focus: Option<&str>, tris: &[Tri]) -> Result<Vec<Vec3>> {
    if let Some(name) = focus {
        if let Some(m) = solver.muscles().iter().find(|m| m.name == name) {
            return Ok(m.x[..m.surface_count].to_vec());
        }
        if let Some(t) = solver.targets().iter().find(|t| t.name == name) {
            return Ok(t
                .positions()
                .iter()
                .map(|&p| t.transform.transform_point3(p))
                .collect());
        }
        return Err(
            format!("--focus {name}: the scene has no muscle, skin or bone of that name").into(),
        );
    }
    let muscle_points: Vec<Vec3> = solver
        .muscles()
        .iter()
        .flat_map(|m| m.x[..m.surface_count].iter().copied())
        .collect();
    Ok(if muscle_points.is_empty() {
        tris.iter().flat_map(|t| t.p).collect()
    } else {
        muscle_points
    })
}

/// Renders the solver's current state as RGB pixels (`options.size`);
/// [`SkinDraw::Compare`] draws two halves from the same camera.
pub fn draw(solver: &Solver, options: &RenderOptions) -> Result<Vec<u8>> {
    let (width, height) = options.size;
    let focus = options.focus.as_deref();
    let camera = (options.view, margin(focus));
    let picture = |skin: SkinDraw, width: u32| -> Result<Vec<u8>> {
        let tris = collect(solver, options.bones, skin);
        let framed = framed_points(solver, focus, &tris)?;
        Ok(rasterise(&tris, &framed, camera, width, height))
    };
    if options.skin != SkinDraw::Compare {
        return picture(options.skin, width);
    }
    let half = (width / 2).max(1);
    let left = picture(SkinDraw::Skinned, half)?;
    let right = picture(SkinDraw::Displacement, half)?;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    let row = half as usize * 3;
    for y in 0..height as usize {
        let out = &mut rgb[y * width as usize * 3..];
        out[..row].copy_from_slice(&left[y * row..(y + 1) * row]);
        out[row..2 * row].copy_from_slice(&right[y * row..(y + 1) * row]);
    }
    Ok(rgb)
}

/// How much wider than what it frames the picture is: a little with every
/// muscle in view, twice as wide around a focused body (to see what is
/// around it).
fn margin(focus: Option<&str>) -> f32 {
    if focus.is_some() { 2.0 } else { 1.15 }
}

/// Draws `tris` seen from `view`, framing `framed` (the picture `margin`
/// times as wide).
fn rasterise(
    tris: &[Tri],
    framed: &[Vec3],
    (view, margin): (View, f32),
    width: u32,
    height: u32,
) -> Vec<u8> {
    // Camera basis: looking along −dir, Y up.
    let back = view.direction();
    let right = Vec3::Y.cross(back).normalize();
    let up = back.cross(right);
    let to_camera = Mat3::from_cols(right, up, back).transpose();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in framed {
        let c = to_camera * *p;
        lo = lo.min(c);
        hi = hi.max(c);
    }
    let center = (lo + hi) * 0.5;
    let extent = (hi - lo).truncate().max_element().max(1e-6) * margin;
    let scale = width.min(height) as f32 / extent;
    let (w, h) = (width as usize, height as usize);
    let mut depth = vec![f32::NEG_INFINITY; w * h];
    let mut rgb = vec![0u8; w * h * 3];
    // Background: a soft vertical gradient.
    for y in 0..h {
        let t = y as f32 / h as f32;
        let c = [
            (34.0 + 20.0 * t) as u8,
            (38.0 + 22.0 * t) as u8,
            (46.0 + 26.0 * t) as u8,
        ];
        for x in 0..w {
            rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&c);
        }
    }
    // A light over the camera's shoulder: every view is lit from the front.
    let light = (back + 0.6 * up + 0.3 * right).normalize();
    for t in tris {
        let c = t.p.map(|p| to_camera * p - center);
        let s = c.map(|p| {
            (
                w as f32 * 0.5 + p.x * scale,
                h as f32 * 0.5 - p.y * scale,
                p.z,
            )
        });
        let normal = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        let Some(n) = normal.try_normalize() else {
            continue;
        };
        // Two-sided Lambert with ambient.
        let shade = 0.25 + 0.75 * n.dot(light).abs();
        let color = t.color.map(|k| (k * shade * 255.0).clamp(0.0, 255.0) as u8);
        // Pixel box of the triangle, clipped to the image.
        let lo = s
            .iter()
            .fold(Vec2::INFINITY, |m, v| m.min(Vec2::new(v.0, v.1)));
        let hi = s
            .iter()
            .fold(Vec2::NEG_INFINITY, |m, v| m.max(Vec2::new(v.0, v.1)));
        let (min_x, min_y) = (
            lo.x.floor().max(0.0) as usize,
            lo.y.floor().max(0.0) as usize,
        );
        let max_x = hi.x.ceil().min(w as f32 - 1.0);
        let max_y = hi.y.ceil().min(h as f32 - 1.0);
        if max_x < 0.0 || max_y < 0.0 {
            continue;
        }
        let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[2].0 - s[0].0) * (s[1].1 - s[0].1);
        if area.abs() < 1e-12 {
            continue;
        }
        for y in min_y..=max_y as usize {
            for x in min_x..=max_x as usize {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let edge = |a: (f32, f32, f32), b: (f32, f32, f32)| {
                    (b.0 - a.0) * (py - a.1) - (px - a.0) * (b.1 - a.1)
                };
                let w0 = edge(s[1], s[2]) / area;
                let w1 = edge(s[2], s[0]) / area;
                let w2 = edge(s[0], s[1]) / area;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * s[0].2 + w1 * s[1].2 + w2 * s[2].2;
                let i = y * w + x;
                if z > depth[i] {
                    depth[i] = z;
                    rgb[i * 3..i * 3 + 3].copy_from_slice(&color);
                }
            }
        }
    }
    rgb
}

/// Writes RGB pixels as a PNG.
pub fn write_png(path: &Path, rgb: &[u8], width: u32, height: u32) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgb)?;
    Ok(())
}

/// Simulates `frame` frames of `scene` and renders the result.
pub fn run(scene: &str, frame: u32, options: &RenderOptions, out: &Path) -> Result<ExitCode> {
    let (_, mut solver) = load_solver(scene)?;
    for _ in 0..frame {
        solver.step();
    }
    let rgb = draw(&solver, options)?;
    let (width, height) = options.size;
    write_png(out, &rgb, width, height)?;
    println!("{}: frame {frame}, {width}×{height}", out.display());
    Ok(ExitCode::SUCCESS)
}
