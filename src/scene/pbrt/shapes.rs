//! Shapes: triangle meshes, PLY meshes, subdivision surfaces, spheres, disks, cylinders,
//! bilinear patches and curves (diced, `curves.rs`), made world-space triangles and spheres of the
//! scene.

use super::*;

/// The triangles of a mesh made in one piece of the parallel emit.
pub(super) const EMIT_PIECE: usize = 1 << 16;

/// The most triangles a `loopsubdiv` may make.
pub(super) const MAX_SUBDIVIDED_TRIANGLES: f64 = 8_000_000.0;

/// Segments of a triangulated disk.
pub(super) const DISK_SEGMENTS: usize = 128;

/// Segments around a triangulated whole cylinder.
pub(super) const CYLINDER_SEGMENTS: usize = 128;

/// A shape as declared, in its object space, with what applies to it.
#[derive(Clone, Debug)]
pub(super) struct ShapeDecl {
    pub(super) kind: ShapeKind,
    pub(super) ctm: Mat4,
    pub(super) reverse: bool,
    pub(super) material: MaterialRef,
    pub(super) area: Option<AreaLight>,
    pub(super) alpha: Option<crate::scene::Alpha>,
    /// The media it bounds, where they differ (`MediumInterface`).
    pub(super) media: Option<crate::scene::MediumInterface>,
}

impl ShapeDecl {
    /// The triangles it adds to the scene: a mesh's (before degenerate ones are dropped);
    /// the other kinds are analytic or a few triangles.
    pub(super) fn triangles(&self) -> usize {
        match &self.kind {
            ShapeKind::Mesh { indices, .. } => indices.len() / 3,
            _ => 0,
        }
    }
}

#[derive(Clone, Debug)]
pub(super) enum ShapeKind {
    Mesh {
        p: Vec<Vec3>,
        indices: Vec<u32>,
        n: Option<Vec<Vec3>>,
        uv: Option<Vec<Vec2>>,
    },
    Sphere {
        radius: f32,
    },
}

/// The triangle with its orientation reversed (its geometric normal flipped).
pub(super) fn flip(t: Triangle) -> Triangle {
    t.flipped()
}

impl Parser {
    /// pbrt-v4's displaced `plymesh`: refined to edges shorter than `edge_length` in
    /// rendering space, each vertex moved along its normal by the float texture `value`
    /// at its (u, v) and its object-space point (pbrt-v4 evaluates the texture there, not
    /// in rendering space), the normals made again (src/scene/displace.rs).
    fn displaced(
        &self,
        mesh: crate::scene::ply::PlyMesh,
        value: Value,
        edge_length: f32,
        path: &std::path::Path,
    ) -> Result<ShapeKind, String> {
        let Some(uv) = mesh.uv else {
            return Err(format!(
                "a displaced mesh needs (u, v) at its vertices, and {} has none \
                 (pbrt-v4 requires them too)",
                path.display()
            ));
        };
        let n = match mesh.n {
            Some(n) => n,
            None => crate::scene::displace::vertex_normals(&mesh.p, &mesh.indices),
        };
        let source = crate::scene::displace::DisplacedMesh {
            p: mesh.p,
            n,
            uv,
            indices: mesh.indices,
        };
        let ctm = self.gs.ctm;
        // The texture, or a constant (a "float displacement" rather than a texture).
        let texture = match value {
            Value::Texture(t) => Ok(&self.scene.textures[t as usize]),
            Value::Const(c) => Err(c.x),
        };
        let out = crate::scene::displace::displace(
            &source,
            edge_length,
            crate::scene::displace::MAX_DISPLACED_TRIANGLES,
            |a, b| ctm.transform_point3(a).distance(ctm.transform_point3(b)),
            |p, n, uv| match texture {
                Ok(t) => crate::texture::texture_value(t, uv, p, n).x,
                Err(c) => c,
            },
        )?;
        Ok(ShapeKind::Mesh {
            p: out.p,
            indices: out.indices,
            n: Some(out.n),
            uv: Some(out.uv),
        })
    }

    pub(super) fn shape(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "Shape";
        let vec3s = |p: &Param| {
            p.nums
                .chunks(3)
                .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                .collect::<Vec<_>>()
        };
        // A float parameter's first value, or `default`.
        let float_or = |n: &str, default: f64| {
            params
                .find(n)
                .and_then(|p| p.nums.first().copied())
                .unwrap_or(default) as f32
        };
        let kind = match ty {
            "trianglemesh" | "bilinearmesh" => {
                let Some(pp) = params.find("P") else {
                    return Err(self.err_at(file, line, d, format!("{ty}: no \"point3 P\"")));
                };
                let p = vec3s(pp);
                let corners = if ty == "trianglemesh" { 3 } else { 4 };
                let mut indices: Vec<u32> = match params.find("indices") {
                    Some(ip) => {
                        if let Some(bad) = ip.nums.iter().find(|&&x| x < 0.0) {
                            return Err(self.err_at(ip.file, ip.line, d, format!("{ty}: a negative index {bad}")));
                        }
                        ip.nums.iter().map(|&x| x as u32).collect()
                    }
                    None if p.len() == corners => (0..corners as u32).collect(),
                    None => return Err(self.err_at(file, line, d, format!("{ty}: no \"integer indices\" (needed unless there are exactly {corners} points)"))),
                };
                if indices.len() % corners != 0 {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!(
                            "{ty}: {} indices, not a multiple of {corners}",
                            indices.len()
                        ),
                    ));
                }
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= p.len()) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("{ty}: index {bad} out of range ({} points)", p.len()),
                    ));
                }
                let n = match params.find("N") {
                    Some(np) => {
                        let n = vec3s(np);
                        if n.len() != p.len() {
                            return Err(self.err_at(
                                np.file,
                                np.line,
                                d,
                                format!("{ty}: {} normals for {} points", n.len(), p.len()),
                            ));
                        }
                        Some(n)
                    }
                    None => None,
                };
                let uv = match params.find("uv") {
                    Some(up) => {
                        let uv: Vec<Vec2> = up
                            .nums
                            .chunks(2)
                            .map(|c| Vec2::new(c[0] as f32, c[1] as f32))
                            .collect();
                        if uv.len() != p.len() {
                            return Err(self.err_at(
                                up.file,
                                up.line,
                                d,
                                format!("{ty}: {} uv for {} points", uv.len(), p.len()),
                            ));
                        }
                        Some(uv)
                    }
                    None => None,
                };
                if corners == 4 {
                    // A bilinear patch p00 p10 p01 p11 as two triangles (exact when planar).
                    indices = indices
                        .chunks(4)
                        .flat_map(|q| [q[0], q[1], q[3], q[0], q[3], q[2]])
                        .collect();
                }
                params.find("faceIndices");
                if corners == 3 {
                    params.find("S");
                }
                ShapeKind::Mesh { p, indices, n, uv }
            }
            "loopsubdiv" => {
                let Some(pp) = params.find("P") else {
                    return Err(self.err_at(file, line, d, "loopsubdiv: no \"point3 P\""));
                };
                let p = vec3s(pp);
                let Some(ip) = params.find("indices") else {
                    return Err(self.err_at(file, line, d, "loopsubdiv: no \"integer indices\""));
                };
                if let Some(bad) = ip.nums.iter().find(|&&x| x < 0.0) {
                    return Err(self.err_at(
                        ip.file,
                        ip.line,
                        d,
                        format!("loopsubdiv: a negative index {bad}"),
                    ));
                }
                let indices: Vec<u32> = ip.nums.iter().map(|&x| x as u32).collect();
                let levels = params
                    .find("levels")
                    .and_then(|lp| lp.nums.first().copied())
                    .unwrap_or(3.0);
                // Each level multiplies the triangles by 4.
                let triangles = (indices.len() / 3) as f64 * 4f64.powf(levels.max(0.0));
                if !(0.0..=12.0).contains(&levels) || triangles > MAX_SUBDIVIDED_TRIANGLES {
                    return Err(self.err_at(file, line, d, format!("loopsubdiv: {levels} levels would make {triangles} triangles (at most {MAX_SUBDIVIDED_TRIANGLES})")));
                }
                let (p, indices, n) =
                    crate::scene::subdiv::loop_subdivide(&p, &indices, levels as u32)
                        .map_err(|e| self.err_at(file, line, d, format!("loopsubdiv: {e}")))?;
                ShapeKind::Mesh {
                    p,
                    indices,
                    n: Some(n),
                    uv: None,
                }
            }
            "plymesh" => {
                let Some(fp) = params.find("filename").cloned() else {
                    return Err(self.err_at(file, line, d, "plymesh: no \"string filename\""));
                };
                let path = self.resolve(fp.file, &fp.strs[0]);
                let mesh = crate::scene::ply::read_ply(&path)
                    .map_err(|e| self.err_at(fp.file, fp.line, d, e))?;
                let displacement = self.value(params, "displacement", true, d)?;
                let edge_length = float_or("edgelength", 1.0);
                match displacement {
                    None => ShapeKind::Mesh {
                        p: mesh.p,
                        indices: mesh.indices,
                        n: mesh.n,
                        uv: mesh.uv,
                    },
                    Some(value) => {
                        let dp = params.find("displacement").expect("just read");
                        let (dfile, dline) = (dp.file, dp.line);
                        self.read_images()?;
                        self.displaced(mesh, value, edge_length, &path)
                            .map_err(|e| self.err_at(dfile, dline, d, format!("plymesh: {e}")))?
                    }
                }
            }
            "curve" => {
                let Some(pp) = params.find("P") else {
                    return Err(self.err_at(file, line, d, "curve: no \"point3 P\""));
                };
                let cp = vec3s(pp);
                let string = |n: &str, default: &str| {
                    params
                        .find(n)
                        .and_then(|p| p.strs.first().cloned())
                        .unwrap_or_else(|| default.to_owned())
                };
                let width = float_or("width", 1.0) as f64;
                let (width0, width1) = (float_or("width0", width), float_or("width1", width));
                if !(width0 >= 0.0 && width1 >= 0.0) {
                    return Err(self.err_at(file, line, d, "curve: a negative width"));
                }
                let degree = float_or("degree", 3.0) as usize;
                let bspline = match string("basis", "bezier").as_str() {
                    "bezier" => false,
                    "bspline" => true,
                    other => {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!(
                                "curve: basis \"{other}\" (expected \"bezier\" or \"bspline\")"
                            ),
                        ))
                    }
                };
                let ty = match string("type", "flat").as_str() {
                    "flat" => curves::CurveType::Flat,
                    "cylinder" => curves::CurveType::Cylinder,
                    "ribbon" => curves::CurveType::Ribbon,
                    other => {
                        return Err(self.err_at(file, line, d, format!("curve: type \"{other}\" (expected \"flat\", \"cylinder\" or \"ribbon\")")))
                    }
                };
                // (pbrt-v4's GPU renderer dices curves whole, as here: no split depth.)
                params.find("splitdepth");
                let mut curve = curves::Curve {
                    cp,
                    degree,
                    bspline,
                    width0,
                    width1,
                    ty,
                    normals: Vec::new(),
                };
                let segments = curve
                    .segments()
                    .map_err(|e| self.err_at(pp.file, pp.line, d, format!("curve: {e}")))?;
                let normals = params.find("N").map(vec3s);
                match (ty, normals) {
                    (curves::CurveType::Ribbon, Some(n)) if n.len() == segments.len() + 1 => {
                        curve.normals = n
                    }
                    (curves::CurveType::Ribbon, Some(n)) => {
                        return Err(self.err_at(file, line, d, format!("curve: {} normals for {} segments (a ribbon needs one more normal than segments)", n.len(), segments.len())))
                    }
                    (curves::CurveType::Ribbon, None) => {
                        return Err(self.err_at(file, line, d, "curve: a ribbon needs \"normal N\" at its segments' ends"))
                    }
                    (_, Some(_)) => {
                        let at = format!("{}:{line}", self.files[file as usize]);
                        self.warn("curve normals", format!("{at}: curve: normals \"N\" are read by ribbon curves only (ignored, as pbrt-v4 does)"))
                    }
                    (_, None) => {}
                }
                let diced = curve.dice(&segments);
                ShapeKind::Mesh {
                    p: diced.p,
                    indices: diced.indices,
                    n: diced.n,
                    uv: Some(diced.uv),
                }
            }
            "sphere" => {
                let radius = params
                    .find("radius")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(1.0) as f32;
                if !(radius > 0.0) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("sphere: radius must be positive, got {radius}"),
                    ));
                }
                for (name, full) in [("zmin", -radius), ("zmax", radius), ("phimax", 360.0)] {
                    if let Some(p) = params.find(name) {
                        let x = p.nums.first().copied().unwrap_or(full as f64) as f32;
                        let whole = if name == "zmin" {
                            x <= -radius
                        } else {
                            x >= full
                        };
                        if !whole {
                            self.unsupported(
                                p.file,
                                p.line,
                                format!("sphere: {name} (a partial sphere)"),
                            );
                        }
                    }
                }
                ShapeKind::Sphere { radius }
            }
            "disk" => {
                let (radius, inner, height) = (
                    float_or("radius", 1.0),
                    float_or("innerradius", 0.0),
                    float_or("height", 0.0),
                );
                if let Some(p) = params.find("phimax") {
                    if p.nums.first().copied().unwrap_or(360.0) < 360.0 {
                        self.unsupported(p.file, p.line, "disk: phimax (a partial disk)");
                    }
                }
                if !(radius > 0.0 && inner >= 0.0 && inner < radius) {
                    return Err(self.err_at(file, line, d, "disk: need 0 <= innerradius < radius"));
                }
                // An annulus of DISK_SEGMENTS quads (or a fan), normal +z as pbrt's.
                let mut p = Vec::new();
                let mut uv = Vec::new();
                let mut indices = Vec::new();
                for k in 0..DISK_SEGMENTS {
                    let phi = k as f32 / DISK_SEGMENTS as f32 * std::f32::consts::TAU;
                    let (s, c) = phi.sin_cos();
                    p.push(Vec3::new(radius * c, radius * s, height));
                    p.push(Vec3::new(inner * c, inner * s, height));
                    let u = k as f32 / DISK_SEGMENTS as f32;
                    uv.push(Vec2::new(u, 0.0));
                    uv.push(Vec2::new(u, 1.0 - inner / radius));
                }
                for k in 0..DISK_SEGMENTS as u32 {
                    let next = (k + 1) % DISK_SEGMENTS as u32;
                    let (o0, i0, o1, i1) = (2 * k, 2 * k + 1, 2 * next, 2 * next + 1);
                    indices.extend([o0, o1, i1]);
                    if inner > 0.0 {
                        indices.extend([o0, i1, i0]);
                    }
                }
                ShapeKind::Mesh {
                    p,
                    indices,
                    n: None,
                    uv: Some(uv),
                }
            }
            "cylinder" => {
                let (radius, z0, z1, phimax) = (
                    float_or("radius", 1.0),
                    float_or("zmin", -1.0),
                    float_or("zmax", 1.0),
                    float_or("phimax", 360.0).clamp(0.0, 360.0),
                );
                let (zmin, zmax) = (z0.min(z1), z0.max(z1));
                if !(radius > 0.0 && zmax > zmin && phimax > 0.0) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        "cylinder: need radius > 0, zmin != zmax and phimax > 0",
                    ));
                }
                // pbrt-v4's quadric (u = φ / φmax, v = (z − zmin) / (zmax − zmin), the
                // normal away from the axis) as CYLINDER_SEGMENTS quads around, radial
                // vertex normals: exact along z, its area 0.04 % below the cylinder's
                // (the disk's polygon).
                let steps = ((CYLINDER_SEGMENTS as f32 * phimax / 360.0).ceil() as usize).max(1);
                let mut p = Vec::new();
                let mut n = Vec::new();
                let mut uv = Vec::new();
                let mut indices = Vec::new();
                for k in 0..=steps {
                    let u = k as f32 / steps as f32;
                    let (s, c) = (u * phimax.to_radians()).sin_cos();
                    for (z, v) in [(zmin, 0.0), (zmax, 1.0)] {
                        p.push(Vec3::new(radius * c, radius * s, z));
                        n.push(Vec3::new(c, s, 0.0));
                        uv.push(Vec2::new(u, v));
                    }
                    if k > 0 {
                        let (a0, a1, b0, b1) = (
                            2 * k as u32 - 2,
                            2 * k as u32 - 1,
                            2 * k as u32,
                            2 * k as u32 + 1,
                        );
                        // Wound so that the faces' normal leaves the axis.
                        indices.extend([a0, b0, b1, a0, b1, a1]);
                    }
                }
                ShapeKind::Mesh {
                    p,
                    indices,
                    n: Some(n),
                    uv: Some(uv),
                }
            }
            other => {
                self.unsupported(file, line, format!("Shape \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
                return Ok(());
            }
        };
        // pbrt-v4's alpha: a float or a float texture; 1 (opaque) by default.
        let alpha = match self.value(params, "alpha", true, d)? {
            None => None,
            Some(Value::Const(c)) if c.x >= 1.0 => None,
            Some(Value::Const(c))
                if c.x <= 0.0
                    && self.gs.area.is_none()
                    && matches!(kind, ShapeKind::Sphere { .. }) =>
            {
                // pbrt-v4 never intersects a shape whose alpha is 0: a sphere's is nothing,
                // and is left out (triangles keep it: the alpha test cuts them out of every
                // ray; an area light's is an invisible light, below).
                for p in &params.0 {
                    p.used.set(true);
                }
                return Ok(());
            }
            Some(Value::Const(c)) => Some(crate::scene::Alpha::Constant(c.x)),
            Some(Value::Texture(t)) => Some(crate::scene::Alpha::Texture(t)),
        };
        let invisible = alpha.is_some_and(crate::scene::Alpha::is_zero);
        if alpha.is_some() {
            // (An emitting sphere of alpha 0 is an invisible light: left out of the
            // acceleration structures, `emit`. Other alpha on a sphere is refused.)
            if matches!(kind, ShapeKind::Sphere { .. }) && !(invisible && self.gs.area.is_some()) {
                self.unsupported(
                    file,
                    line,
                    "Shape \"sphere\": alpha (lightpath cuts out triangles only; a sphere light's alpha may be 0, an invisible light)",
                );
            }
            // pbrt-v4's invisible area light: alpha 0 on an emitter (its triangles cut out
            // of every ray; the emitter table marks it EMITTER_HIDDEN).
            if self.gs.area.is_some() && !invisible {
                self.unsupported(
                    file,
                    line,
                    format!("Shape \"{ty}\": alpha on an area light"),
                );
            }
        }
        let refused: &[&str] = match ty {
            "bilinearmesh" => &["emissionfilename"],
            _ => &[],
        };
        for &name in refused {
            if let Some(p) = params.find(name) {
                self.unsupported(p.file, p.line, format!("Shape \"{ty}\": {name}"));
            }
        }
        self.check_used(d, &format!("\"{ty}\""), params);
        let decl = ShapeDecl {
            kind,
            ctm: self.gs.ctm,
            reverse: self.gs.reverse,
            material: self.gs.material.clone(),
            area: self.gs.area.clone(),
            alpha,
            media: self.medium_transition().or_else(|| {
                // An area light in a medium (no transition): its subpaths start there.
                let outside = self.gs.media.1;
                (self.gs.area.is_some() && outside.is_some()).then_some(
                    crate::scene::MediumInterface {
                        inside: outside,
                        outside,
                    },
                )
            }),
        };
        if matches!(decl.material, MaterialRef::Interface)
            && decl.media.is_some()
            && decl.area.is_some()
        {
            self.unsupported(
                file,
                line,
                format!("Shape \"{ty}\": an area light on an interface material"),
            );
        }
        if self.defining.is_some() {
            if decl.area.is_some() {
                self.unsupported(file, line, "an area light inside an object instance");
            }
            if let Some((_, shapes, _)) = &mut self.defining {
                shapes.push(decl);
            }
            return Ok(());
        }
        if let Some((name, named, shape)) = self.deferring.take() {
            self.deferred.push((decl, name, named, shape));
            return Ok(());
        }
        self.check_triangles(decl.triangles(), file, line, d)?;
        self.emit(decl)
    }

    /// Adds a declared shape to the scene, in world space.
    pub(super) fn emit(&mut self, s: ShapeDecl) -> Result<(), ParseError> {
        // An interface material bounds media; where it bounds none it is nothing.
        if matches!(s.material, MaterialRef::Interface) && s.media.is_none() {
            return Ok(());
        }
        let ctm = s.ctm;
        let swaps = Mat3::from_mat4(ctm).determinant() < 0.0;
        let area = |tris: &[Triangle]| {
            tris.iter()
                .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
                .sum::<f32>()
        };
        match s.kind {
            ShapeKind::Mesh { p, indices, n, uv } => {
                // (Carried to the world in place: a mesh of millions of vertices would
                // otherwise touch as much fresh memory again.)
                let mut wp = p;
                for x in &mut wp {
                    *x = ctm.transform_point3(*x);
                }
                let normal_matrix = Mat3::from_mat4(ctm).inverse().transpose();
                let wn: Option<Vec<Vec3>> = n.map(|mut n| {
                    for x in &mut n {
                        let v = (normal_matrix * *x).normalize_or_zero();
                        *x = if s.reverse { -v } else { v };
                    }
                    n
                });
                let emission = s
                    .area
                    .as_ref()
                    .map(|a| (a.radiance * self.imaging_ratio(), a.two_sided));
                let power = s.area.as_ref().and_then(|a| {
                    a.power
                        .map(|phi| (phi, if a.two_sided { 2.0 } else { 1.0 }))
                });
                let index = self.intern_ref(&s.material, emission, s.media);
                // Triangle `c`'s record, or None where it has no area.
                let make = |c: &[u32]| {
                    let (a, b, cc) = (c[0] as usize, c[1] as usize, c[2] as usize);
                    let mut t = Triangle::new([wp[a], wp[b], wp[cc]], index);
                    // pbrt's default uv for a triangle without them: (0,0), (1,0), (1,1).
                    t.uv = Some(match &uv {
                        Some(uv) => [uv[a], uv[b], uv[cc]],
                        None => crate::scene::DEFAULT_UV,
                    });
                    t.alpha = s.alpha;
                    if (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length_squared() == 0.0 {
                        return None;
                    }
                    // A normal a singular transform squashed to nothing (its inverse
                    // transpose does not exist): the triangle shades by its geometric
                    // normal instead.
                    let normals = wn
                        .as_ref()
                        .map(|wn| [wn[a], wn[b], wn[cc]])
                        .filter(|n| n.iter().all(|v| *v != Vec3::ZERO));
                    Some(match normals {
                        Some(n) => {
                            t.normals = Some(n);
                            t.facing_its_normals()
                        }
                        // pbrt flips the geometric normal for reverse orientation or a
                        // transform that swaps handedness.
                        None if s.reverse ^ swaps => flip(t),
                        None => t,
                    })
                };
                self.scene.triangles.reserve(indices.len() / 3);
                match (power, emission) {
                    // pbrt-v4 makes one light per triangle of a mesh, each emitting
                    // `power`: radiance power / (sides π area) per triangle.
                    (Some((phi, sides)), Some((e, two_sided))) => {
                        for t in indices.chunks(3).filter_map(make) {
                            let scale = phi
                                / (sides * area(std::slice::from_ref(&t)) * std::f32::consts::PI);
                            let material =
                                self.intern_ref(&s.material, Some((e * scale, two_sided)), s.media);
                            self.scene.triangles.push(Triangle { material, ..t });
                        }
                    }
                    // Made in pieces on every core (Triangles::extend_in_parallel).
                    _ => self
                        .scene
                        .triangles
                        .extend_in_parallel(&indices, EMIT_PIECE, make),
                }
            }
            ShapeKind::Sphere { radius } => {
                let emission = s.area.as_ref().map(|a| {
                    let mut e = a.radiance * self.imaging_ratio();
                    if let Some(phi) = a.power {
                        let scale = Mat3::from_mat4(ctm);
                        let r = radius * scale.determinant().abs().cbrt();
                        let sides = if a.two_sided { 2.0 } else { 1.0 };
                        e *= phi
                            / (sides * 4.0 * std::f32::consts::PI * r * r * std::f32::consts::PI);
                    }
                    (e, a.two_sided)
                });
                let material = self.intern_ref(&s.material, emission, s.media);
                self.scene.spheres.push(Sphere {
                    object_to_world: ctm * Mat4::from_scale(Vec3::splat(radius)),
                    material,
                    inward: s.reverse ^ swaps,
                    hidden: emission.is_some() && s.alpha.is_some_and(crate::scene::Alpha::is_zero),
                });
            }
        }
        Ok(())
    }
}
