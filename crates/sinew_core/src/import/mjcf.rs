//! A reader for the part of MuJoCo's MJCF that describes anatomy: `<include>`
//! files, `<default>` classes, `<compiler>` units, mesh assets, the body tree
//! with hinge / slide / ball joints, mesh geoms and sites, spatial tendons and
//! the actuators that pull on them.
//!
//! Everything is kept in MuJoCo's frames (Z-up, metres); [`MjcfModel::attach`]
//! composes models (optionally mirrored), the importer converts to Y-up.
//!
//! Not read (documented in `ARCHITECTURE.md`): wrapping geoms of tendons (the
//! path runs through the sites only), equality constraints between joints,
//! inertia, contacts, `<frame>` elements and free joints (an error names them).

use crate::error::ImportError;
use crate::skeleton::{JointCoupling, JointKind, JointSpec};
use glam::{Quat, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod nesting;
mod reader;

/// Where an element was read: file and 1-based line.
#[derive(Clone, Debug, PartialEq)]
pub struct Origin {
    /// File.
    pub file: Arc<Path>,
    /// 1-based line.
    pub line: u32,
}

impl Origin {
    pub(crate) fn error(&self, element: &str, reason: impl Into<String>) -> ImportError {
        ImportError::Model {
            file: self.file.to_path_buf(),
            line: self.line,
            element: element.to_string(),
            reason: reason.into(),
        }
    }
}

/// A rigid body.
#[derive(Clone, Debug)]
pub struct MjBody {
    /// Name (generated as `body<N>` when the file gives none).
    pub name: String,
    /// Parent body index; `None` = the world.
    pub parent: Option<usize>,
    /// Position in the parent frame. Units: m.
    pub pos: Vec3,
    /// Orientation in the parent frame.
    pub quat: Quat,
    /// Joints (angles in radians, lengths in metres).
    pub joints: Vec<JointSpec>,
    /// Where it was read.
    pub origin: Origin,
}

/// A site: a named point fixed to a body.
#[derive(Clone, Debug)]
pub struct MjSite {
    /// Name.
    pub name: String,
    /// Body index; `None` = the world.
    pub body: Option<usize>,
    /// Position in the body frame. Units: m.
    pub pos: Vec3,
    /// Orientation in the body frame.
    pub quat: Quat,
}

/// A mesh asset.
#[derive(Clone, Debug)]
pub struct MjMesh {
    /// Asset name.
    pub name: String,
    /// Resolved file path.
    pub file: PathBuf,
    /// Per-axis scale (a negative component mirrors the mesh).
    pub scale: Vec3,
}

/// A mesh geom: a mesh asset placed in a body.
#[derive(Clone, Debug)]
pub struct MjGeom {
    /// Geom name (may be empty).
    pub name: String,
    /// Body index; `None` = the world.
    pub body: Option<usize>,
    /// Mesh asset name.
    pub mesh: String,
    /// Position in the body frame. Units: m.
    pub pos: Vec3,
    /// Orientation in the body frame.
    pub quat: Quat,
}

/// A spatial tendon: the sites its path runs through, in order.
#[derive(Clone, Debug)]
pub struct MjTendon {
    /// Name.
    pub name: String,
    /// Site names along the path, each with where it was named. They are
    /// resolved by [`MjcfModel::tendon_sites`], after composition, because a
    /// fragment's tendons may run through sites of the model it attaches to.
    pub sites: Vec<(String, Origin)>,
    /// The wrapping geoms along the path, each between two of `sites`.
    pub wraps: Vec<TendonWrap>,
    /// Where it was read.
    pub origin: Origin,
}

/// A wrapping geom on a tendon's path (`<spatial><geom geom sidesite>`).
#[derive(Clone, Debug)]
pub struct TendonWrap {
    /// How many of the tendon's sites come before it: it lies between
    /// sites `after − 1` and `after`.
    pub after: usize,
    /// The geom's name (a [`MjWrapGeom`]).
    pub geom: String,
    /// The site that picks the side the path wraps on, if named.
    pub sidesite: Option<String>,
    /// Where it was named.
    pub origin: Origin,
}

/// A sphere or cylinder geom: an obstacle a tendon's path may wrap around.
#[derive(Clone, Debug)]
pub struct MjWrapGeom {
    /// Name.
    pub name: String,
    /// Body index; `None` = the world.
    pub body: Option<usize>,
    /// Its shape.
    pub shape: WrapShape,
    /// Position in the body frame. Units: m.
    pub pos: Vec3,
    /// Orientation in the body frame (a cylinder's axis is its local Z).
    pub quat: Quat,
}

/// The shape of a [`MjWrapGeom`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WrapShape {
    /// A sphere of this radius (m).
    Sphere {
        /// Radius. Units: m.
        radius: f32,
    },
    /// An infinite cylinder of this radius (m) about the local Z axis (a
    /// path wraps it as MuJoCo does, whatever its length).
    Cylinder {
        /// Radius. Units: m.
        radius: f32,
    },
}

/// An actuator acting on a tendon.
#[derive(Clone, Debug)]
pub struct MjActuator {
    /// Name.
    pub name: String,
    /// Tendon index.
    pub tendon: usize,
    /// Maximum isometric force when the model gives one. Units: N.
    pub force: Option<f32>,
}

/// A parsed model.
#[derive(Clone, Debug, Default)]
pub struct MjcfModel {
    /// The main file.
    pub file: PathBuf,
    /// Bodies, parents before children.
    pub bodies: Vec<MjBody>,
    /// Sites.
    pub sites: Vec<MjSite>,
    /// Mesh assets.
    pub meshes: Vec<MjMesh>,
    /// Mesh geoms.
    pub geoms: Vec<MjGeom>,
    /// Named sphere and cylinder geoms (what tendons wrap around).
    pub wrap_geoms: Vec<MjWrapGeom>,
    /// Spatial tendons.
    pub tendons: Vec<MjTendon>,
    /// Tendon actuators.
    pub actuators: Vec<MjActuator>,
    /// Joint equalities (`<equality><joint joint1 joint2 polycoef>`).
    pub couplings: Vec<JointCoupling>,
}

/// An XML element with `<include>`s expanded, owning its data.
#[derive(Clone, Debug)]
struct Element {
    tag: String,
    attrs: Vec<(String, String)>,
    children: Vec<Element>,
    origin: Origin,
}

impl Element {
    fn get(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }
}

const MAX_INCLUDE_DEPTH: usize = 16;
/// Deepest element nesting read: every later walk over the tree (defaults,
/// bodies) recurses at most this deep, so no file can exhaust the stack.
/// myo-sim's deepest is about 20.
const MAX_ELEMENT_DEPTH: usize = 256;

/// Reads `path` with its includes; `chain` holds the files that include it
/// (outermost first), so an include cycle is named file by file.
fn read_element(path: &Path, chain: &[PathBuf]) -> Result<Element, ImportError> {
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    if let Some((line, element)) = nesting::too_deep(&text, MAX_ELEMENT_DEPTH) {
        return Err(ImportError::Model {
            file: path.to_path_buf(),
            line: line as u32,
            element: element.into(),
            reason: format!("elements nested more than {MAX_ELEMENT_DEPTH} deep"),
        });
    }
    let doc = roxmltree::Document::parse(&text).map_err(|e| {
        let pos = e.pos();
        ImportError::Xml {
            file: path.to_path_buf(),
            line: pos.row,
            column: pos.col,
            reason: e.to_string(),
        }
    })?;
    let file: Arc<Path> = Arc::from(path);
    let mut chain = chain.to_vec();
    chain.push(path.canonicalize().unwrap_or_else(|_| path.to_path_buf()));
    convert(&doc, doc.root_element(), &file, &chain, 0)
}

fn convert(
    doc: &roxmltree::Document,
    node: roxmltree::Node,
    file: &Arc<Path>,
    chain: &[PathBuf],
    nesting: usize,
) -> Result<Element, ImportError> {
    let origin = Origin {
        file: file.clone(),
        line: doc.text_pos_at(node.range().start).row,
    };
    if nesting >= MAX_ELEMENT_DEPTH {
        return Err(origin.error(
            node.tag_name().name(),
            format!("elements nested more than {MAX_ELEMENT_DEPTH} deep"),
        ));
    }
    let mut children = Vec::new();
    for child in node.children().filter(|n| n.is_element()) {
        if child.tag_name().name() == "include" {
            let here = Origin {
                file: file.clone(),
                line: doc.text_pos_at(child.range().start).row,
            };
            let name = child
                .attribute("file")
                .ok_or_else(|| here.error("include", "missing attribute 'file'"))?;
            let target = file.parent().unwrap_or(Path::new(".")).join(name);
            if !target.is_file() {
                return Err(here.error(
                    "include",
                    format!("included file '{}' does not exist", target.display()),
                ));
            }
            let canonical = target.canonicalize().unwrap_or_else(|_| target.clone());
            if let Some(first) = chain.iter().position(|f| *f == canonical) {
                let cycle: Vec<String> = chain[first..]
                    .iter()
                    .chain([&canonical])
                    .map(|f| f.display().to_string())
                    .collect();
                return Err(here.error("include", format!("include cycle: {}", cycle.join(" → "))));
            }
            if chain.len() >= MAX_INCLUDE_DEPTH {
                return Err(here.error(
                    "include",
                    format!("includes nested more than {MAX_INCLUDE_DEPTH} deep"),
                ));
            }
            let included = read_element(&target, chain)?;
            children.extend(included.children);
        } else {
            children.push(convert(doc, child, file, chain, nesting + 1)?);
        }
    }
    Ok(Element {
        tag: node.tag_name().name().to_string(),
        attrs: node
            .attributes()
            .map(|a| (a.name().to_string(), a.value().to_string()))
            .collect(),
        children,
        origin,
    })
}

/// `class → tag → attributes`, each class already merged with its parents.
type Defaults = HashMap<String, HashMap<String, Vec<(String, String)>>>;

fn read_defaults(
    e: &Element,
    inherited: &HashMap<String, Vec<(String, String)>>,
    out: &mut Defaults,
) {
    let class = e.get("class").unwrap_or("main").to_string();
    let mut own = inherited.clone();
    for c in e.children.iter().filter(|c| c.tag != "default") {
        let slot = own.entry(c.tag.clone()).or_default();
        for (k, v) in &c.attrs {
            match slot.iter_mut().find(|(sk, _)| sk == k) {
                Some(existing) => existing.1 = v.clone(),
                None => slot.push((k.clone(), v.clone())),
            }
        }
    }
    for c in e.children.iter().filter(|c| c.tag == "default") {
        read_defaults(c, &own, out);
    }
    out.insert(class, own);
}

#[derive(Clone, Debug)]
struct Compiler {
    degrees: bool,
    euler_sequence: String,
    mesh_dir: String,
}

/// An element's attributes with its class defaults behind them.
struct Attrs<'e> {
    element: &'e Element,
    defaults: Option<&'e Vec<(String, String)>>,
}

impl<'e> Attrs<'e> {
    fn get(&self, name: &str) -> Option<&'e str> {
        self.element.get(name).or_else(|| {
            self.defaults?
                .iter()
                .find(|(k, _)| k == name)
                .map(|(_, v)| v.as_str())
        })
    }
}

struct Reader<'a> {
    main_dir: PathBuf,
    defaults: &'a Defaults,
    compiler: Compiler,
    model: MjcfModel,
    site_index: HashMap<String, usize>,
}

fn floats(origin: &Origin, tag: &str, name: &str, text: &str) -> Result<Vec<f32>, ImportError> {
    text.split_whitespace()
        .map(|t| {
            t.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    origin.error(
                        tag,
                        format!("attribute '{name}': '{t}' is not a finite number"),
                    )
                })
        })
        .collect()
}

impl MjcfModel {
    /// Reads an MJCF file (a `<mujoco>` model or a `<mujocoinclude>` fragment)
    /// with its includes.
    pub fn load(path: &Path) -> Result<Self, ImportError> {
        let root = read_element(path, &[])?;
        if root.tag != "mujoco" && root.tag != "mujocoinclude" {
            return Err(root.origin.error(
                &root.tag,
                "root element must be <mujoco> or <mujocoinclude>",
            ));
        }
        let mut defaults = Defaults::new();
        defaults.insert("main".into(), HashMap::new());
        let mut compiler = Compiler {
            degrees: true,
            euler_sequence: "xyz".into(),
            mesh_dir: String::new(),
        };
        for c in &root.children {
            match c.tag.as_str() {
                "default" => {
                    let inherited = defaults.get("main").cloned().unwrap_or_default();
                    read_defaults(c, &inherited, &mut defaults);
                }
                "compiler" => {
                    if let Some(a) = c.get("angle") {
                        compiler.degrees = match a {
                            "degree" => true,
                            "radian" => false,
                            _ => return Err(c.origin.error("compiler", format!("angle '{a}'"))),
                        };
                    }
                    if let Some(s) = c.get("eulerseq") {
                        compiler.euler_sequence = s.to_string();
                    }
                    if let Some(d) = c.get("meshdir") {
                        compiler.mesh_dir = d.to_string();
                    }
                }
                _ => {}
            }
        }
        let mut reader = Reader {
            main_dir: path.parent().unwrap_or(Path::new(".")).to_path_buf(),
            defaults: &defaults,
            compiler,
            model: MjcfModel {
                file: path.to_path_buf(),
                ..Default::default()
            },
            site_index: HashMap::new(),
        };
        // Bodies and sites first (tendons refer to sites), then assets,
        // tendons and actuators, in file order within each.
        for c in root.children.iter().filter(|c| c.tag == "worldbody") {
            reader.children(c, None, "main")?;
        }
        for c in root.children.iter().filter(|c| c.tag == "asset") {
            for m in c.children.iter().filter(|m| m.tag == "mesh") {
                reader.mesh_asset(m)?;
            }
        }
        for c in root.children.iter().filter(|c| c.tag == "tendon") {
            for t in c.children.iter().filter(|t| t.tag == "spatial") {
                reader.tendon(t)?;
            }
        }
        for c in root.children.iter().filter(|c| c.tag == "equality") {
            for e in c.children.iter().filter(|e| e.tag == "joint") {
                reader.coupling(e)?;
            }
        }
        for c in root.children.iter().filter(|c| c.tag == "actuator") {
            for a in &c.children {
                reader.actuator(a)?;
            }
        }
        Ok(reader.model)
    }

    /// Index of a body by name.
    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.name == name)
    }

    /// Index of a site by name.
    pub fn site_index(&self, name: &str) -> Option<usize> {
        self.sites.iter().position(|s| s.name == name)
    }

    /// The sites of tendon `t`'s path, in order; a missing site is an error
    /// naming the file and line that refers to it.
    pub fn tendon_sites(&self, t: usize) -> Result<Vec<&MjSite>, ImportError> {
        let tendon = &self.tendons[t];
        tendon
            .sites
            .iter()
            .map(|(name, origin)| {
                self.site_index(name)
                    .map(|i| &self.sites[i])
                    .ok_or_else(|| {
                        origin.error(
                            "site",
                            format!(
                                "tendon '{}' names site '{name}', which does not exist",
                                tendon.name
                            ),
                        )
                    })
            })
            .collect()
    }

    /// A wrapping geom by name. A left-side name ([`left_name`]'s `_l`)
    /// that the model does not hold falls back to the name without it: a
    /// mirrored tendon may wrap a geom of the model it attaches to that
    /// serves both sides (myo-sim's thorax ellipsoid for either pectoralis,
    /// with a side site per side).
    pub fn wrap_geom(&self, name: &str) -> Option<&MjWrapGeom> {
        let find = |n: &str| self.wrap_geoms.iter().find(|g| g.name == n);
        find(name).or_else(|| name.strip_suffix("_l").and_then(find))
    }

    /// A mesh asset by name.
    pub fn mesh(&self, name: &str) -> Option<&MjMesh> {
        self.meshes.iter().find(|m| m.name == name)
    }

    /// Attaches `child`'s root bodies at site `site` of this model (an empty
    /// name: at the world origin, as myo-sim attaches the legs). With
    /// `mirror`, the child is first reflected through its local XY plane
    /// (z → −z, as myo-sim builds a left arm from the right one) and renamed:
    /// a trailing `_r` becomes `_l`, other names get `_l` appended.
    pub fn attach(
        &mut self,
        child: &MjcfModel,
        site: &str,
        mirror: bool,
    ) -> Result<(), ImportError> {
        let (site_body, site_pos, site_quat) = if site.is_empty() {
            (None, Vec3::ZERO, Quat::IDENTITY)
        } else {
            let s = self
                .site_index(site)
                .ok_or_else(|| ImportError::UnknownName {
                    context: format!("attaching {}", child.file.display()),
                    kind: "site",
                    name: site.to_string(),
                })?;
            (self.sites[s].body, self.sites[s].pos, self.sites[s].quat)
        };
        let child = if mirror {
            child.mirrored()
        } else {
            child.clone()
        };
        let (b0, t0) = (self.bodies.len(), self.tendons.len());
        for mut b in child.bodies {
            match b.parent {
                Some(p) => b.parent = Some(p + b0),
                None => {
                    b.parent = site_body;
                    b.pos = site_pos + site_quat * b.pos;
                    b.quat = site_quat * b.quat;
                }
            }
            self.bodies.push(b);
        }
        let reparent = |body: Option<usize>| body.map(|b| b + b0).or(site_body);
        self.sites.extend(child.sites.into_iter().map(|mut x| {
            x.body = reparent(x.body);
            x
        }));
        self.geoms.extend(child.geoms.into_iter().map(|mut g| {
            g.body = reparent(g.body);
            g
        }));
        self.wrap_geoms
            .extend(child.wrap_geoms.into_iter().map(|mut g| {
                g.body = reparent(g.body);
                g
            }));
        for m in child.meshes {
            if self.mesh(&m.name).is_none() {
                self.meshes.push(m);
            }
        }
        self.tendons.extend(child.tendons);
        self.actuators
            .extend(child.actuators.into_iter().map(|mut a| {
                a.tendon += t0;
                a
            }));
        self.couplings.extend(child.couplings);
        let mut names = std::collections::HashSet::new();
        for b in &self.bodies {
            if !names.insert(&b.name) {
                return Err(b.origin.error(
                    "body",
                    format!("duplicate body name '{}' after attaching", b.name),
                ));
            }
        }
        Ok(())
    }

    /// This model reflected through z = 0 of every local frame, renamed to the
    /// left side.
    pub fn mirrored(&self) -> MjcfModel {
        let reflect = |v: Vec3| Vec3::new(v.x, v.y, -v.z);
        // A rotation R becomes M R M: its axis maps to −M·axis.
        let reflect_quat = |q: Quat| Quat::from_xyzw(-q.x, -q.y, q.z, q.w);
        let mut m = self.clone();
        for b in &mut m.bodies {
            b.name = left_name(&b.name);
            b.pos = reflect(b.pos);
            b.quat = reflect_quat(b.quat);
            for j in &mut b.joints {
                j.name = left_name(&j.name);
                j.anchor = reflect(j.anchor);
                // Hinges keep their angle sense; slides move along the mirrored axis.
                j.axis = match j.kind {
                    JointKind::Slide => reflect(j.axis),
                    _ => -reflect(j.axis),
                };
            }
        }
        let place = |name: &mut String, pos: &mut Vec3, quat: &mut Quat| {
            *name = left_name(name);
            *pos = reflect(*pos);
            *quat = reflect_quat(*quat);
        };
        for s in &mut m.sites {
            place(&mut s.name, &mut s.pos, &mut s.quat);
        }
        for g in &mut m.geoms {
            place(&mut g.name, &mut g.pos, &mut g.quat);
            g.mesh = left_name(&g.mesh);
        }
        for g in &mut m.wrap_geoms {
            place(&mut g.name, &mut g.pos, &mut g.quat);
        }
        for mesh in &mut m.meshes {
            mesh.name = left_name(&mesh.name);
            mesh.scale.z = -mesh.scale.z;
        }
        for t in &mut m.tendons {
            t.name = left_name(&t.name);
            for (site, _) in &mut t.sites {
                *site = left_name(site);
            }
            for w in &mut t.wraps {
                w.geom = left_name(&w.geom);
                w.sidesite = w.sidesite.as_deref().map(left_name);
            }
        }
        for a in &mut m.actuators {
            a.name = left_name(&a.name);
        }
        for c in &mut m.couplings {
            c.joint = left_name(&c.joint);
            c.driver = c.driver.as_deref().map(left_name);
        }
        m
    }
}

/// `humerus_r` → `humerus_l`; `DELT1` → `DELT1_l`.
pub fn left_name(name: &str) -> String {
    match name.strip_suffix("_r") {
        Some(stem) => format!("{stem}_l"),
        None if name.is_empty() => String::new(),
        None => format!("{name}_l"),
    }
}
