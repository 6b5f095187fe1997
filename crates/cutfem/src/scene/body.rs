//! The body of a scene as a signed distance grid (the levelset of thesis sec. 2.5.2.1, negative
//! inside, stored on the world grid of sec. 4.3.1; the cut cells come from it):
//! an `.sdf`/`.npy` file as given (or resampled to another resolution), a mesh or shape sampled
//! at `[body].resolution`, padded so the body does not touch the grid border.

use super::*;

/// Default grid resolution (cells per world unit) of meshes and shapes when `body.resolution`
/// is absent.
pub const DEFAULT_RESOLUTION: f64 = 20.0;
/// Empty cells added around a body (the diffusion band of sec. 4.4.5 reaches 5 nodes out).
pub const PADDING_CELLS: usize = 6;

impl Scene {
    /// Loads or builds the reference SDF of the body (world units, negative inside), padded so
    /// that the body does not touch the grid border.
    pub fn body_sdf(&self) -> Result<crate::SdfGrid, Error> {
        self.body_sdf_at(None)
    }

    /// The body's resolution in grid cells per world unit: `[body].resolution` (default
    /// [`DEFAULT_RESOLUTION`]) for a mesh or shape, `1 / spacing` for an SDF file.
    pub fn resolution(&self) -> Result<f64, Error> {
        Ok(match &self.body.sdf {
            Some(_) => 1.0 / self.body_sdf()?.spacing,
            None => self.body.resolution.unwrap_or(DEFAULT_RESOLUTION),
        })
    }

    /// [`Scene::body_sdf`] at `resolution` cells per unit instead of the scene's (`None`: the
    /// scene's). A mesh or shape is sampled at that resolution; an SDF file, which carries its
    /// own, is resampled from its trilinear interpolant (the same body, a finer or coarser
    /// simulation grid), nodes on multiples of the new spacing.
    pub fn body_sdf_at(&self, resolution: Option<f64>) -> Result<crate::SdfGrid, Error> {
        let b = &self.body;
        if let (Some(r), Some(_)) = (resolution, &b.sdf) {
            let own = Scene {
                body: BodySection {
                    resolution: None,
                    ..b.clone()
                },
                ..self.clone()
            }
            .body_sdf()?;
            return resample(&own, r).map_err(|e| Error::format(&self.path, e));
        }
        let resolution = resolution.or(b.resolution).unwrap_or(DEFAULT_RESOLUTION);
        let sdf = if let Some(p) = &b.sdf {
            let path = self.resolve(p);
            let ext = path
                .extension()
                .and_then(|e| e.to_str())
                .unwrap_or("")
                .to_ascii_lowercase();
            let grid = match ext.as_str() {
                "sdf" => crate::SdfGrid::read_sdf(&path)?,
                "npy" => {
                    let origin = b.origin.ok_or_else(|| {
                        Error::format(&self.path, "body.origin is required for an .npy SDF")
                    })?;
                    let spacing = b.spacing.ok_or_else(|| {
                        Error::format(&self.path, "body.spacing is required for an .npy SDF")
                    })?;
                    crate::SdfGrid::read_npy(&path, origin, spacing)?
                }
                other => {
                    return Err(Error::format(
                        &self.path,
                        extension_error("body.sdf", &path, other, ".sdf, .npy"),
                    ))
                }
            };
            grid.validate().map_err(|e| Error::format(&path, e.to_string()))?;
            pad(&grid, PADDING_CELLS).map_err(|e| Error::format(&path, e))?
        } else if let Some(p) = &b.mesh {
            let path = self.resolve(p);
            if let Some(hit) = mesh_cache_get(&path, resolution) {
                return Ok(hit);
            }
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            if !["obj", "stl", "ply"].contains(&ext.to_ascii_lowercase().as_str()) {
                let msg = extension_error("body.mesh", &path, ext, ".obj, .stl, .ply");
                return Err(Error::format(&self.path, msg));
            }
            let mesh = crate::TriMesh::load(&path)?;
            let sdf = mesh
                .to_sdf(resolution, PADDING_CELLS)
                .map_err(|e| Error::format(&path, e.to_string()))?;
            if let Some((lo, hi)) = mesh.bounding_box() {
                sdf.check_sampled_body(lo, hi)
                    .map_err(|e| Error::format(&path, e))?;
            }
            mesh_cache_put(&path, resolution, &sdf);
            sdf
        } else if let Some(shape) = &b.shape {
            // its messages name `body.shape` already
            shape
                .validate()
                .map_err(|e| Error::format(&self.path, e.to_string()))?;
            let sdf = shape
                .to_sdf(resolution, PADDING_CELLS)
                .map_err(|e| Error::format(&self.path, e.to_string()))?;
            let (lo, hi) = shape.bounding_box();
            sdf.check_sampled_body(lo, hi)
                .map_err(|e| Error::format(&self.path, e))?;
            sdf
        } else {
            return Err(Error::format(
                &self.path,
                "body: give exactly one of `sdf`, `mesh`, `shape`",
            ));
        };
        Ok(sdf)
    }
}

/// `"KEY: `FILE` has no extension (supported: ...)"` or `"KEY: unsupported extension `.EXT`
/// (supported: ...)"`.
pub fn extension_error(key: &str, path: &Path, ext: &str, supported: &str) -> String {
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    if ext.is_empty() {
        format!(
            "{key}: `{}` has no extension (supported: {supported})",
            quote(&name, MAX_QUOTE)
        )
    } else {
        format!(
            "{key}: unsupported extension `.{}` of `{}` (supported: {supported})",
            quote(ext, MAX_QUOTE),
            quote(&name, MAX_QUOTE)
        )
    }
}

/// Adds `cells` layers of nodes around an SDF grid; the new values grow by the distance to
/// the old border. Refuses a body that reaches the border (it would be cut off).
pub fn pad(g: &crate::SdfGrid, cells: usize) -> Result<crate::SdfGrid, String> {
    let [nx, ny, nz] = g.dims;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let border = i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz;
                if border && g.values[i + nx * (j + ny * k)] < 0.0 {
                    return Err(format!(
                        "the body reaches the border of its SDF grid at node ({i}, {j}, {k}): it lies partly outside the grid"
                    ));
                }
            }
        }
    }
    let p = cells as i64;
    let dims = [nx + 2 * cells, ny + 2 * cells, nz + 2 * cells];
    let h = g.spacing;
    let origin = [
        g.origin[0] - p as f64 * h,
        g.origin[1] - p as f64 * h,
        g.origin[2] - p as f64 * h,
    ];
    let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] as i64 {
        for j in 0..dims[1] as i64 {
            for i in 0..dims[0] as i64 {
                let (oi, oj, ok) = (i - p, j - p, k - p);
                let ci = oi.clamp(0, nx as i64 - 1);
                let cj = oj.clamp(0, ny as i64 - 1);
                let ck = ok.clamp(0, nz as i64 - 1);
                let d = (((oi - ci).pow(2) + (oj - cj).pow(2) + (ok - ck).pow(2)) as f64).sqrt() * h;
                values.push(g.values[ci as usize + nx * (cj as usize + ny * ck as usize)] + d);
            }
        }
    }
    Ok(crate::SdfGrid {
        exact: None,
        origin,
        spacing: h,
        dims,
        values,
    })
}

/// `g` resampled at `resolution` cells per unit from its trilinear interpolant, over the box of
/// its inside nodes plus [`PADDING_CELLS`] cells (nodes on multiples of the new spacing).
fn resample(g: &crate::SdfGrid, resolution: f64) -> Result<crate::SdfGrid, String> {
    let (lo, hi) = g
        .bounding_box_of_inside()
        .ok_or_else(|| "body.sdf: the SDF has no inside node".to_string())?;
    // one old cell of margin: the interpolant's zero level lies within a cell of an inside node
    let pad = g.spacing;
    let lo = lo.map(|x| x - pad);
    let hi = hi.map(|x| x + pad);
    let (origin, dims) =
        crate::SdfGrid::covering_grid(lo, hi, resolution, PADDING_CELLS).map_err(|e| e.to_string())?;
    let far = g.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    Ok(crate::SdfGrid::from_fn(origin, 1.0 / resolution, dims, |p| {
        g.sample(p).unwrap_or(far)
    }))
}
