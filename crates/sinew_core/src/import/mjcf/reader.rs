//! The body tree reader: bodies, joints, geoms, sites, tendons and
//! actuators of one MJCF element tree, with default classes applied.

use super::*;

impl<'a> Reader<'a> {
    /// Attributes of `e`, falling back to its default class.
    fn attr<'e>(&self, e: &'e Element, class: &str) -> Attrs<'e>
    where
        'a: 'e,
    {
        let class = e.get("class").unwrap_or(class);
        let defaults: &'a Defaults = self.defaults;
        Attrs {
            element: e,
            defaults: defaults
                .get(class)
                .or_else(|| defaults.get("main"))
                .and_then(|d| d.get(&e.tag)),
        }
    }

    fn vector<const N: usize>(
        &self,
        e: &Element,
        name: &str,
        value: Option<&str>,
    ) -> Result<Option<[f32; N]>, ImportError> {
        let Some(text) = value else { return Ok(None) };
        let v = floats(&e.origin, &e.tag, name, text)?;
        let array: [f32; N] = v.try_into().map_err(|v: Vec<f32>| {
            e.origin.error(
                &e.tag,
                format!("attribute '{name}' needs {N} numbers, has {}", v.len()),
            )
        })?;
        Ok(Some(array))
    }

    fn angle(&self, a: f32) -> f32 {
        if self.compiler.degrees {
            a.to_radians()
        } else {
            a
        }
    }

    /// Position and orientation of a body, geom or site.
    fn frame(&self, e: &Element, attrs: &Attrs) -> Result<(Vec3, Quat), ImportError> {
        let get = |n: &str| attrs.get(n);
        let pos = self
            .vector::<3>(e, "pos", get("pos"))?
            .map_or(Vec3::ZERO, Vec3::from);
        let quat = if let Some([w, x, y, z]) = self.vector::<4>(e, "quat", get("quat"))? {
            Quat::from_xyzw(x, y, z, w)
        } else if let Some([x, y, z, a]) = self.vector::<4>(e, "axisangle", get("axisangle"))? {
            let axis = Vec3::new(x, y, z)
                .try_normalize()
                .ok_or_else(|| e.origin.error(&e.tag, "axisangle has a zero axis"))?;
            Quat::from_axis_angle(axis, self.angle(a))
        } else if let Some(angles) = self.vector::<3>(e, "euler", get("euler"))? {
            let seq = &self.compiler.euler_sequence;
            let mut q = Quat::IDENTITY;
            for (c, a) in seq.chars().zip(angles) {
                let axis = match c.to_ascii_lowercase() {
                    'x' => Vec3::X,
                    'y' => Vec3::Y,
                    'z' => Vec3::Z,
                    _ => return Err(e.origin.error(&e.tag, format!("eulerseq '{seq}'"))),
                };
                let r = Quat::from_axis_angle(axis, self.angle(a));
                // Lower case: rotating (intrinsic) axes; upper case: fixed axes.
                q = if c.is_ascii_lowercase() { q * r } else { r * q };
            }
            q
        } else if let Some([ax, ay, az, bx, by, bz]) =
            self.vector::<6>(e, "xyaxes", get("xyaxes"))?
        {
            let x = Vec3::new(ax, ay, az).normalize_or_zero();
            let y = (Vec3::new(bx, by, bz) - x * x.dot(Vec3::new(bx, by, bz))).normalize_or_zero();
            if x == Vec3::ZERO || y == Vec3::ZERO {
                return Err(e.origin.error(&e.tag, "xyaxes are degenerate"));
            }
            Quat::from_mat3(&glam::Mat3::from_cols(x, y, x.cross(y)))
        } else if let Some(z) = self.vector::<3>(e, "zaxis", get("zaxis"))? {
            let z = Vec3::from(z)
                .try_normalize()
                .ok_or_else(|| e.origin.error(&e.tag, "zaxis has zero length"))?;
            Quat::from_rotation_arc(Vec3::Z, z)
        } else {
            Quat::IDENTITY
        };
        Ok((pos, quat.normalize()))
    }

    fn body(&mut self, e: &Element, parent: Option<usize>, class: &str) -> Result<(), ImportError> {
        let index = self.model.bodies.len();
        let attrs = self.attr(e, class);
        let name = attrs
            .get("name")
            .map_or_else(|| format!("body{index}"), str::to_string);
        let (pos, quat) = self.frame(e, &attrs)?;
        let child_class = e.get("childclass").unwrap_or(class).to_string();
        self.model.bodies.push(MjBody {
            name,
            parent,
            pos,
            quat,
            joints: Vec::new(),
            origin: e.origin.clone(),
        });
        self.children(e, Some(index), &child_class)
    }

    pub(super) fn children(
        &mut self,
        e: &Element,
        body: Option<usize>,
        class: &str,
    ) -> Result<(), ImportError> {
        for c in &e.children {
            match c.tag.as_str() {
                "body" => self.body(c, body, class)?,
                "joint" => {
                    let joint = self.joint(c, class)?;
                    let b = body.ok_or_else(|| c.origin.error("joint", "a joint needs a body"))?;
                    self.model.bodies[b].joints.push(joint);
                }
                "freejoint" => {
                    return Err(c.origin.error(
                        "freejoint",
                        "joint type 'free' is not supported (sinew poses the root from the scene)",
                    ));
                }
                "geom" => self.geom(c, body, class)?,
                "site" => self.site(c, body, class)?,
                "frame" => {
                    return Err(c
                        .origin
                        .error("frame", "<frame> elements are not supported"));
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn joint(&self, e: &Element, class: &str) -> Result<JointSpec, ImportError> {
        let attrs = self.attr(e, class);
        let get = |n: &str| attrs.get(n);
        let name = get("name").unwrap_or_default().to_string();
        let kind = match get("type").unwrap_or("hinge") {
            "hinge" => JointKind::Hinge,
            "slide" => JointKind::Slide,
            "ball" => JointKind::Ball,
            other => {
                return Err(e.origin.error(
                    "joint",
                    format!("joint '{name}' has type '{other}', which sinew does not support (hinge, slide, ball)"),
                ));
            }
        };
        let anchor = self
            .vector::<3>(e, "pos", get("pos"))?
            .map_or(Vec3::ZERO, Vec3::from);
        let axis = self
            .vector::<3>(e, "axis", get("axis"))?
            .map_or(Vec3::Z, Vec3::from);
        if kind != JointKind::Ball && axis.length_squared() == 0.0 {
            return Err(e
                .origin
                .error("joint", format!("joint '{name}' has a zero axis")));
        }
        let limited = get("limited").is_none_or(|l| l != "false");
        let range = match self.vector::<2>(e, "range", get("range"))? {
            Some([lo, hi]) if limited && kind == JointKind::Hinge => {
                Some((self.angle(lo), self.angle(hi)))
            }
            Some([lo, hi]) if limited && kind == JointKind::Slide => Some((lo, hi)),
            _ => None,
        };
        if let Some((lo, hi)) = range
            && lo > hi
        {
            return Err(e
                .origin
                .error("joint", format!("joint '{name}' range is empty")));
        }
        Ok(JointSpec {
            name,
            kind,
            anchor,
            axis: axis.normalize_or_zero(),
            range,
        })
    }

    fn geom(&mut self, e: &Element, body: Option<usize>, class: &str) -> Result<(), ImportError> {
        let attrs = self.attr(e, class);
        let get = |n: &str| attrs.get(n);
        if let Some(shape) = self.wrap_shape(e, &attrs)? {
            let (pos, quat) = self.frame(e, &attrs)?;
            self.model.wrap_geoms.push(MjWrapGeom {
                name: get("name").unwrap_or_default().to_string(),
                body,
                shape,
                pos,
                quat,
            });
            return Ok(());
        }
        let Some(mesh) = get("mesh") else {
            return Ok(());
        };
        if get("type").is_some_and(|t| t != "mesh") {
            return Ok(());
        }
        let (pos, quat) = self.frame(e, &attrs)?;
        self.model.geoms.push(MjGeom {
            name: get("name").unwrap_or_default().to_string(),
            body,
            mesh: mesh.to_string(),
            pos,
            quat,
        });
        Ok(())
    }

    /// A named sphere (MJCF's default type) or cylinder geom's shape: what
    /// a tendon can wrap around (radius 0 where it has no size). `None`
    /// for any other geom.
    fn wrap_shape(&self, e: &Element, attrs: &Attrs) -> Result<Option<WrapShape>, ImportError> {
        let get = |n: &str| attrs.get(n);
        if get("name").is_none_or(str::is_empty) || get("mesh").is_some() {
            return Ok(None);
        }
        let kind = get("type").unwrap_or("sphere");
        if kind != "sphere" && kind != "cylinder" {
            return Ok(None);
        }
        // Checked where a tendon wraps it (a geom no tendon names may do
        // without).
        let radius = match get("size") {
            Some(text) => floats(&e.origin, &e.tag, "size", text)?
                .first()
                .copied()
                .unwrap_or(0.0),
            None => 0.0,
        };
        Ok(Some(if kind == "sphere" {
            WrapShape::Sphere { radius }
        } else {
            WrapShape::Cylinder { radius }
        }))
    }

    fn site(&mut self, e: &Element, body: Option<usize>, class: &str) -> Result<(), ImportError> {
        let attrs = self.attr(e, class);
        let get = |n: &str| attrs.get(n);
        let Some(name) = get("name") else {
            return Ok(());
        };
        let (pos, quat) = self.frame(e, &attrs)?;
        if self
            .site_index
            .insert(name.to_string(), self.model.sites.len())
            .is_some()
        {
            return Err(e
                .origin
                .error("site", format!("duplicate site name '{name}'")));
        }
        self.model.sites.push(MjSite {
            name: name.to_string(),
            body,
            pos,
            quat,
        });
        Ok(())
    }

    pub(super) fn mesh_asset(&mut self, e: &Element) -> Result<(), ImportError> {
        let attrs = self.attr(e, "main");
        let get = |n: &str| attrs.get(n);
        let file = get("file").ok_or_else(|| e.origin.error("mesh", "missing attribute 'file'"))?;
        let name = get("name").map(str::to_string).unwrap_or_else(|| {
            Path::new(file)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
        let scale = self
            .vector::<3>(e, "scale", get("scale"))?
            .map_or(Vec3::ONE, Vec3::from);
        let path = Path::new(file);
        let file = if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.main_dir.join(&self.compiler.mesh_dir).join(path)
        };
        self.model.meshes.push(MjMesh { name, file, scale });
        Ok(())
    }

    pub(super) fn tendon(&mut self, e: &Element) -> Result<(), ImportError> {
        let name = e.get("name").unwrap_or_default().to_string();
        let mut sites = Vec::new();
        let mut wraps = Vec::new();
        for c in &e.children {
            match c.tag.as_str() {
                "site" => {
                    let site = c
                        .get("site")
                        .ok_or_else(|| c.origin.error("site", "missing attribute 'site'"))?;
                    sites.push((site.to_string(), c.origin.clone()));
                }
                "geom" => {
                    let geom = c
                        .get("geom")
                        .ok_or_else(|| c.origin.error("geom", "missing attribute 'geom'"))?;
                    wraps.push(TendonWrap {
                        after: sites.len(),
                        geom: geom.to_string(),
                        sidesite: c.get("sidesite").map(str::to_string),
                        origin: c.origin.clone(),
                    });
                }
                "pulley" => {
                    return Err(c.origin.error(
                        "pulley",
                        format!("tendon '{name}': branching tendons (pulleys) are not supported"),
                    ));
                }
                _ => {}
            }
        }
        // MuJoCo's rule: a wrapping geom lies between two sites.
        if let Some(w) = wraps
            .iter()
            .find(|w| w.after == 0 || w.after == sites.len())
        {
            return Err(w.origin.error(
                "geom",
                format!(
                    "tendon '{name}': wrapping geom '{}' must lie between two sites",
                    w.geom
                ),
            ));
        }
        self.model.tendons.push(MjTendon {
            name,
            sites,
            wraps,
            origin: e.origin.clone(),
        });
        Ok(())
    }

    pub(super) fn coupling(&mut self, e: &Element) -> Result<(), ImportError> {
        let attrs = self.attr(e, "main");
        if attrs.get("active") == Some("false") {
            return Ok(());
        }
        let joint = attrs
            .get("joint1")
            .ok_or_else(|| e.origin.error("joint", "equality needs 'joint1'"))?;
        let mut polynomial = [0.0, 1.0, 0.0, 0.0, 0.0];
        if let Some(text) = attrs.get("polycoef") {
            let v = floats(&e.origin, "joint", "polycoef", text)?;
            for (slot, value) in polynomial.iter_mut().zip(v) {
                *slot = value;
            }
        }
        self.model.couplings.push(JointCoupling {
            joint: joint.to_string(),
            driver: attrs.get("joint2").map(str::to_string),
            polynomial,
        });
        Ok(())
    }

    pub(super) fn actuator(&mut self, e: &Element) -> Result<(), ImportError> {
        let attrs = self.attr(e, "main");
        let get = |n: &str| attrs.get(n);
        let Some(tendon) = get("tendon") else {
            return Ok(());
        };
        let index = self
            .model
            .tendons
            .iter()
            .position(|t| t.name == tendon)
            .ok_or_else(|| {
                e.origin.error(
                    &e.tag,
                    format!("actuator names tendon '{tendon}', which does not exist"),
                )
            })?;
        let force = match e.tag.as_str() {
            "muscle" => get("force")
                .map(|f| floats(&e.origin, &e.tag, "force", f))
                .transpose()?
                .and_then(|v| v.first().copied()),
            "general" if get("gaintype") == Some("muscle") => get("gainprm")
                .map(|g| floats(&e.origin, &e.tag, "gainprm", g))
                .transpose()?
                .and_then(|v| v.get(2).copied()),
            _ => None,
        }
        .filter(|&f| f > 0.0);
        self.model.actuators.push(MjActuator {
            name: get("name").unwrap_or(tendon).to_string(),
            tendon: index,
            force,
        });
        Ok(())
    }
}
