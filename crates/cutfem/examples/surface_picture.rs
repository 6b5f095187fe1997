//! Extracts the surface of a thesis `.sdf` file by marching cubes and renders it to a PNG.
//!
//! `cargo run --release -p cutfem --example surface_picture -- [IN.sdf] [OUT.png]`
//! (defaults: `../shared/data/sdf/bunny_small.sdf`, `docs/img/bunny_small_surface.png`,
//! relative to the workspace root).

use cutfem::render::{self, Camera, Coloring, Ground, RenderItem, RenderOptions};
use cutfem::surface::extract_surface;
use cutfem::SdfGrid;
use std::path::{Path, PathBuf};

fn main() -> Result<(), cutfem::Error> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut args = std::env::args().skip(1);
    let input = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("../shared/data/sdf/bunny_small.sdf"));
    let output = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("docs/img/bunny_small_surface.png"));

    let sdf = SdfGrid::read_sdf(&input)?;
    let surface = extract_surface(&sdf);
    let mesh = &surface.mesh;
    let Some((lo, hi)) = render::bounds(&[mesh]) else {
        return Err(cutfem::Error::Invalid(format!(
            "{}: empty surface",
            input.display()
        )));
    };
    let camera = Camera::framing(lo, hi, 0.5, 0.3);
    let size = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    let options = RenderOptions {
        ground: Some(Ground {
            height: lo[1],
            cell: size / 4.0,
            extent: 2.0 * size,
            ..Ground::default()
        }),
        supersample: 3,
        ..RenderOptions::default()
    };
    let item = RenderItem {
        mesh,
        coloring: Coloring::Uniform([205, 160, 110]),
    };
    let mut image = render::render(&[item], &camera, 640, 480, &options);
    let name = input.file_stem().and_then(|s| s.to_str()).unwrap_or("surface");
    image.label(&format!(
        "{name}: marching cubes, {} vertices, {} triangles",
        mesh.vertices.len(),
        mesh.faces.len()
    ));
    if let Some(dir) = output.parent() {
        std::fs::create_dir_all(dir).map_err(|e| cutfem::Error::io(dir, e))?;
    }
    image.save_png(&output)?;
    println!(
        "{}: {} vertices, {} triangles -> {}",
        input.display(),
        mesh.vertices.len(),
        mesh.faces.len(),
        output.display()
    );
    Ok(())
}
