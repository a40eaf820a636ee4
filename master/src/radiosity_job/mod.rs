//! The offline radiosity job behind `showcase-master radiosity` and
//! `bench radiosity`: load a scene, mesh and solve it (augmented radiosity
//! when it has real objects and projectors), and write `solution.ply`,
//! the projectors' irradiance maps and the virtual objects' light maps.

pub mod bench;
pub mod captured;
pub mod consistency;
pub mod export;
pub mod gpu_hemicube;
pub mod live;
pub mod report;

pub use bench::{BenchRecord, bench_radiosity, bench_radiosity_at};

use anyhow::Context;
use glam::DVec3;
use showcase_light::radiosity::{
    self, B1Pass, ConvergencePoint, FormFactorMethod, GatherOptions, MeshOptions, RadiosityMesh,
    RefineOptions, SolveOptions, augmented_radiosity_with, gather_adaptive, gathered_b2_vertices,
    irradiance_map, vertex_mesh_from_vertices,
};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::{ObjectKind, Showcase};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Settings of the `radiosity` command (`None`: the default).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RadiosityOptions {
    /// Largest patch area (m^2).
    pub max_patch_area: Option<f64>,
    /// Hemi-cube resolution.
    pub hemicube: Option<u32>,
    /// Unshot-energy threshold.
    pub threshold: Option<f64>,
    /// Told after every shot (progress display).
    pub progress: radiosity::ShotProgress,
    /// Each patch starts as `4^element_depth` elements (default 1).
    pub element_depth: Option<u32>,
    /// Which solver.
    pub solver: Solver,
    /// Most links the hierarchical solver may make (set from the memory
    /// budget when it runs).
    pub max_links: usize,
    /// The hierarchical solver's refinement threshold (fraction of the
    /// injected power a link's error may reach).
    pub epsilon: Option<f64>,
    /// Memory the hierarchical solver may use (MB); default: 80 % of what
    /// the system has available.
    pub max_memory_mb: Option<f64>,
    /// Told at each gather of the hierarchical solver; returning false
    /// stops it (progress display and time budget).
    pub hierarchy_progress: radiosity::HierarchyProgress,
}

/// Which radiosity solver runs (`--solver`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Solver {
    /// Hierarchical above [`AUTO_HIERARCHICAL_ELEMENTS`] elements,
    /// progressive (with its final gather) below.
    #[default]
    Auto,
    /// Progressive refinement with a final gather at the vertices: the
    /// reference, cost about the square of the elements.
    Progressive,
    /// Hierarchical radiosity with clustering
    /// ([`radiosity::hierarchy`]): cost about linear in the elements.
    Hierarchical,
}

/// `--solver auto` solves meshes with more elements than this
/// hierarchically: the progressive solver's time grows as the square of
/// the elements and passes a minute at about this size (ARCHITECTURE.md,
/// Radiosity).
pub const AUTO_HIERARCHICAL_ELEMENTS: usize = 4000;

/// Why a `--solver` value was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("radiosity solver {0:?} is not auto, progressive or hierarchical")]
pub struct BadSolver(pub String);

impl std::str::FromStr for Solver {
    type Err = BadSolver;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(Self::Auto),
            "progressive" => Ok(Self::Progressive),
            "hierarchical" => Ok(Self::Hierarchical),
            other => Err(BadSolver(other.to_string())),
        }
    }
}

/// Where the hemi-cube's item buffers are made (`--form-factors cpu|gpu`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FormFactorDevice {
    /// Rays on the CPU.
    #[default]
    Cpu,
    /// Rasterised on the GPU (wgpu; lavapipe where there is no GPU).
    Gpu,
}

/// Why a `--form-factors` value was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("form-factor device {0:?} is not cpu or gpu")]
pub struct BadFormFactorDevice(pub String);

impl std::str::FromStr for FormFactorDevice {
    type Err = BadFormFactorDevice;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "cpu" => Ok(Self::Cpu),
            "gpu" => Ok(Self::Gpu),
            other => Err(BadFormFactorDevice(other.to_string())),
        }
    }
}

/// Default largest patch area (m^2).
pub const DEFAULT_PATCH_AREA: f64 = 0.01;

impl RadiosityOptions {
    /// These options for `showcase`: its own largest patch area
    /// ([`Showcase::patch_area`], scene key `patch_area`) where the options
    /// name none. Every entry that meshes a scene resolves through here.
    pub fn for_scene(&self, showcase: &Showcase) -> Self {
        Self {
            max_patch_area: self.max_patch_area.or(showcase.patch_area),
            ..self.clone()
        }
    }

    /// The largest patch area these options mesh with (m^2).
    pub fn patch_area(&self) -> f64 {
        self.max_patch_area.unwrap_or(DEFAULT_PATCH_AREA)
    }

    /// The mesh settings.
    pub fn mesh(&self) -> MeshOptions {
        MeshOptions {
            max_patch_area: self.patch_area(),
            element_depth: self.element_depth.unwrap_or(1),
            ..MeshOptions::default()
        }
    }

    /// The mesh of the hierarchical solver: as [`Self::mesh`], but no
    /// element below 1/64 of the largest patch area (the clusters merge
    /// small triangles; splitting a scanned mesh's triangles only
    /// multiplies the links).
    pub fn hierarchical_mesh(&self) -> MeshOptions {
        let m = self.mesh();
        MeshOptions {
            min_element_area: m.max_patch_area / 64.0,
            ..m
        }
    }

    /// The hierarchical solver's settings.
    pub fn hierarchy(&self) -> radiosity::HierarchyOptions {
        let d = radiosity::HierarchyOptions::default();
        radiosity::HierarchyOptions {
            epsilon: self.epsilon.unwrap_or(d.epsilon),
            max_links: if self.max_links > 0 {
                self.max_links
            } else {
                d.max_links
            },
            progress: self.hierarchy_progress.clone(),
            ..d
        }
    }

    /// The solver settings.
    pub fn solve(&self) -> SolveOptions {
        let d = SolveOptions::default();
        SolveOptions {
            hemicube: self.hemicube.unwrap_or(d.hemicube),
            threshold: self.threshold.unwrap_or(d.threshold),
            method: FormFactorMethod::Hybrid,
            progress: self.progress.clone(),
            ..d
        }
    }

    /// [`Self::solve`] with its hemi-cube item buffers made on `device`:
    /// for the GPU this opens a headless device.
    pub fn solve_on(&self, device: FormFactorDevice) -> anyhow::Result<SolveOptions> {
        let mut solve = self.solve();
        if device == FormFactorDevice::Gpu {
            let ctx = showcase_render::gpu::GpuContext::new_headless()
                .context("opening a gpu for --form-factors gpu")?;
            tracing::info!(adapter = %ctx.describe(), "hemi-cube item buffers on the gpu");
            solve.item_buffer = radiosity::shooting::ItemBufferBackend::Raster(
                std::sync::Arc::new(showcase_render::gpu::hemicube::GpuHemiCube::new(&ctx)),
            );
        }
        Ok(solve)
    }
}

/// What a radiosity run did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    /// `progressive` or `hierarchical`.
    pub solver: &'static str,
    /// Links of the hierarchical B0 solve (0 for the progressive solver).
    pub links: usize,
    /// False when a time budget stopped the solve early.
    pub complete: bool,
    /// Patches (shooters).
    pub patches: usize,
    /// Elements (receivers) after refinement.
    pub elements: usize,
    /// Shots over all passes (gathers, for the hierarchical solver).
    pub shots: usize,
    /// Unshot fraction at the end of the B0 solve (the last gather's
    /// relative change, for the hierarchical solver).
    pub unshot_fraction: f64,
    /// Wall-clock seconds of meshing, solving and the irradiance maps.
    pub seconds: f64,
    /// Of which meshing and solving (B0..B3, vertex values).
    pub solve_seconds: f64,
    /// The solution mesh.
    pub solution: PathBuf,
    /// Irradiance maps, one per projector.
    pub irradiance_maps: Vec<PathBuf>,
    /// Light maps, one per virtual object.
    pub light_maps: Vec<PathBuf>,
    /// Clamped fraction of each projector's valid pixels.
    pub clipped_fractions: Vec<f64>,
    /// Real elements whose B2 was clipped at 0.
    pub clipped_elements: usize,
    /// Relative mean |B3 - B0| per RGB channel, when augmented.
    pub b3_b0_deviation_rgb: Option<[f64; 3]>,
    /// Convergence of the B0 solve.
    pub convergence: Vec<ConvergencePoint>,
}

/// A solved scene in memory.
pub struct Solved {
    /// The refined mesh.
    pub mesh: RadiosityMesh,
    /// B0 per element (with the ambient term when not augmented).
    pub b0: Vec<DVec3>,
    /// The augmented passes, when the scene has real objects and projectors.
    pub augmented: Option<radiosity::AugmentedSolution>,
    /// Geometry of the real objects.
    pub real: SceneGeometry,
    /// Shots of the B0 solve (all refinement rounds).
    pub shots: usize,
    /// Unshot fraction at the end of the B0 solve.
    pub unshot_fraction: f64,
    /// Convergence curve of the last B0 round.
    pub convergence: Vec<ConvergencePoint>,
    /// The output mesh: the patches at 16 elements each, refined where B0
    /// changes fast.
    pub output_mesh: RadiosityMesh,
    /// B0 at the output mesh's vertices: by a final gather
    /// ([`radiosity::gather_adaptive`]) after the progressive solver and
    /// after the hierarchical one on a small mesh
    /// ([`HIERARCHICAL_GATHER_PAIRS`]) (point values, not element
    /// averages, so edges and corners are not smeared); on a large mesh
    /// the hierarchical element values averaged to the vertices.
    pub b0_vertices: Vec<DVec3>,
    /// B2 at the vertices of `mesh`, when augmented: the real
    /// interreflection gathered at each vertex after the progressive
    /// solver ([`radiosity::gathered_b2_vertices`]), element B2 averaged
    /// to the vertices after the hierarchical one.
    pub b2_vertices: Option<Vec<DVec3>>,
    /// The solver that ran.
    pub solver: Solver,
    /// Links of the hierarchical B0 solve (0 for the progressive solver).
    pub links: usize,
    /// False when a budget stopped the hierarchical solve early.
    pub complete: bool,
}

/// The global-illumination field for `showcase` as it stands (what the
/// projectors and the faces add, and the real surfaces' own
/// interreflection), seen by the eyes `eyes` ([`live::LiveScene`]: the
/// correction of [`radiosity::augmented::indirect_correction`] with the
/// virtual objects as movers,
/// on the hierarchical mesh and settings of `options`, with the real
/// elements the projectors leave dark: those none reaches and those in an
/// eye's occlusion shadow), and the elements it has.
pub fn indirect_field(
    showcase: &Showcase,
    eyes: &[glam::DVec3],
    options: &RadiosityOptions,
) -> anyhow::Result<(showcase_light::render::IndirectField, usize)> {
    let (mesh, delta) = indirect_values(showcase, &[], eyes, options)?;
    let elements = mesh.elements.len();
    let field = showcase_light::render::IndirectField::new(std::sync::Arc::new(mesh), &delta)?;
    Ok((field, elements))
}

/// [`indirect_field`]'s mesh and per-element values (what the cluster
/// sends the nodes; [`RadiosityOptions::hierarchical_mesh`] meshes it),
/// with the real reflectance from the captured `maps` where the scene
/// names them.
pub fn indirect_values(
    showcase: &Showcase,
    maps: &[showcase_proto::capture::CapturedMap],
    eyes: &[glam::DVec3],
    options: &RadiosityOptions,
) -> anyhow::Result<(RadiosityMesh, Vec<showcase_light::render::IndirectLight>)> {
    let scene = live::LiveScene::new(showcase, maps, options)?;
    let solution = scene.start(showcase)?;
    let values = scene.field(&solution, showcase, eyes)?;
    let mesh = solution.mesh().context("no solution")?.clone();
    Ok((mesh, values))
}

/// Mesh, solve with one round of adaptive refinement, and run the augmented
/// passes when the scene has real objects and projectors.
pub fn solve_showcase(showcase: &Showcase, options: &RadiosityOptions) -> anyhow::Result<Solved> {
    solve_showcase_on(showcase, options, FormFactorDevice::Cpu)
}

/// [`solve_showcase`] with the hemi-cube item buffers made on `device`.
pub fn solve_showcase_on(
    showcase: &Showcase,
    options: &RadiosityOptions,
    device: FormFactorDevice,
) -> anyhow::Result<Solved> {
    let options = &options.for_scene(showcase);
    let all = SceneGeometry::build(showcase, &ObjectFilter::All).context("building geometry")?;
    let real = SceneGeometry::build(showcase, &ObjectFilter::Real).context("building geometry")?;
    let mut mesh = RadiosityMesh::build(showcase, &all, &options.mesh()).context("meshing")?;
    let lights: Vec<_> = showcase.lights.iter().map(|l| l.light.clone()).collect();
    check_solvable(&mesh, &lights)?;
    let hierarchical = match options.solver {
        Solver::Hierarchical => true,
        Solver::Progressive => false,
        Solver::Auto => mesh.elements.len() > AUTO_HIERARCHICAL_ELEMENTS,
    };
    if hierarchical {
        let mesh = RadiosityMesh::build(showcase, &all, &options.hierarchical_mesh())
            .context("meshing")?;
        let max_links = memory_check(mesh.elements.len(), options)?;
        let mut options = options.clone();
        options.max_links = max_links;
        return solve_hierarchical_showcase(showcase, &options, mesh, all, real, &lights);
    }
    let solve = options.solve_on(device)?;
    let solution =
        radiosity::solve_adaptive(&mut mesh, &all, &lights, &solve, &RefineOptions::default())
            .context("solving")?;
    let has_real = showcase.objects.iter().any(|o| o.kind == ObjectKind::Real);
    let augmented = if has_real && !showcase.projectors.is_empty() {
        // One-bounce B1 (B2 = (I - K) B0): with B2 gathered at the
        // vertices it is what reaches the consistency target through the
        // simulated projectors; the paper's converged B1 over-subtracts
        // (bench `augmented` record: 0.026 against 0.56).
        Some(
            augmented_radiosity_with(&mesh, &all, &real, &lights, &solve, B1Pass::OneBounce)
                .context("augmented passes")?,
        )
    } else {
        None
    };
    let b0 = augmented
        .as_ref()
        .map_or(solution.display, |a| a.b0.clone());
    let output_mesh = RadiosityMesh::build(
        showcase,
        &all,
        &MeshOptions {
            element_depth: 2,
            ..options.mesh()
        },
    )
    .context("meshing the output")?;
    let (output_mesh, b0_vertices) = gathered_output(&mesh, &b0, output_mesh, &all, &lights);
    // The real room's interreflection gathered at each vertex, not
    // element B2 averaged to it (radiosity::gathered_b2_vertices).
    let b2_vertices = augmented
        .as_ref()
        .map(|a| gathered_b2_vertices(&mesh, &real, a, &GatherOptions::default()));
    Ok(Solved {
        b0,
        output_mesh,
        b0_vertices,
        b2_vertices,
        mesh,
        augmented,
        real,
        shots: solution.shots,
        unshot_fraction: solution.unshot_fraction,
        convergence: solution.convergence,
        solver: Solver::Progressive,
        links: 0,
        complete: true,
    })
}

/// `output_mesh`, refined where B0 changes fast, and B0 gathered at its
/// vertices from the solution `b0` on `mesh` ([`gather_adaptive`]): both
/// solvers' point values at the output's vertices.
fn gathered_output(
    mesh: &RadiosityMesh,
    b0: &[DVec3],
    mut output_mesh: RadiosityMesh,
    all: &SceneGeometry,
    lights: &[showcase_proto::Light],
) -> (RadiosityMesh, Vec<DVec3>) {
    let (_, values) = gather_adaptive(
        mesh,
        b0,
        &mut output_mesh,
        all,
        lights,
        &GatherOptions::default(),
        &RefineOptions::default(),
    );
    (output_mesh, values)
}

/// Element-vertex pairs up to which the hierarchical path gathers B0 at
/// the output mesh's vertices, for a solve of at most
/// [`AUTO_HIERARCHICAL_ELEMENTS`] elements (Cornell at 0.02 m^2: 824
/// elements; the demo cabinet's 11,988 stay out).
pub const HIERARCHICAL_GATHER_PAIRS: usize = 4_000_000;

/// [`solve_showcase_on`] with the hierarchical solver: B0 (and the
/// augmented passes, one-bounce B1, when the scene has real objects and
/// projectors) on `mesh`; the output mesh is `mesh` itself, or, when
/// small enough ([`HIERARCHICAL_GATHER_PAIRS`]), the scene's plain mesh
/// with B0 gathered at its vertices.
fn solve_hierarchical_showcase(
    showcase: &Showcase,
    options: &RadiosityOptions,
    mesh: RadiosityMesh,
    all: SceneGeometry,
    real: SceneGeometry,
    lights: &[showcase_proto::Light],
) -> anyhow::Result<Solved> {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let has_real = showcase.objects.iter().any(|o| o.kind == ObjectKind::Real);
    // Watch the passes' progress for the B0 links and an early stop.
    let (stopped, b0_links) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicUsize::new(0)),
    );
    let mut h = options.hierarchy();
    let inner = options.hierarchy_progress.clone();
    let (st, bl) = (stopped.clone(), b0_links.clone());
    h.progress = radiosity::HierarchyProgress::new(move |p| {
        // The B0 solve reports first; its links are the largest count.
        bl.fetch_max(p.links, Ordering::Relaxed);
        let go_on = inner.report_to(p);
        if !go_on {
            st.store(true, Ordering::Relaxed);
        }
        go_on
    });
    let (b0, augmented, solution) = if has_real && !showcase.projectors.is_empty() {
        let a = radiosity::augmented_radiosity_hierarchical(
            &mesh,
            &all,
            &real,
            lights,
            &h,
            B1Pass::OneBounce,
        )
        .context("augmented passes")?;
        (a.b0.clone(), Some(a), None)
    } else {
        let s = radiosity::solve_hierarchical(&mesh, &all, lights, &h).context("solving")?;
        (s.radiosity.clone(), None, Some(s))
    };
    // A small mesh gets B0 gathered at the vertices of the output mesh,
    // as the progressive path does: averaging element B to the vertices
    // puts them half an element inside at every edge and corner (Cornell
    // probes: 5.3 % median averaged, 2.7 % gathered).
    // (The plain mesh is built only for a small solve: the cabinet's would
    // hold 46,800 elements for nothing.)
    let small = if mesh.elements.len() <= AUTO_HIERARCHICAL_ELEMENTS {
        let m =
            RadiosityMesh::build(showcase, &all, &options.mesh()).context("meshing the output")?;
        (mesh.elements.len() * m.vertices.len() <= HIERARCHICAL_GATHER_PAIRS).then_some(m)
    } else {
        None
    };
    let (output_mesh, b0_vertices) = match small {
        Some(output_mesh) => gathered_output(&mesh, &b0, output_mesh, &all, lights),
        None => (mesh.clone(), mesh.vertex_values(&b0)),
    };
    let b2_vertices = augmented.as_ref().map(|a| mesh.vertex_values(&a.b2));
    let (iterations, residual) = match &solution {
        Some(s) => (s.iterations as usize, s.residual),
        None => augmented
            .as_ref()
            .map_or((0, 0.0), |a| (a.shots[0], a.b0_residual)),
    };
    let links = b0_links.load(Ordering::Relaxed);
    let complete = !stopped.load(Ordering::Relaxed);
    Ok(Solved {
        output_mesh,
        b0,
        b0_vertices,
        b2_vertices,
        mesh,
        augmented,
        real,
        shots: iterations,
        unshot_fraction: residual,
        convergence: Vec::new(),
        solver: Solver::Hierarchical,
        links,
        complete,
    })
}

/// The memory the hierarchical solver may use (bytes): `--max-memory-mb`,
/// else 80 % of `MemAvailable` in `/proc/meminfo`; `None` when neither is
/// known.
fn memory_budget(options: &RadiosityOptions) -> Option<usize> {
    if let Some(mb) = options.max_memory_mb {
        return Some((mb * 1e6) as usize);
    }
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some((kb * 1024.0 * 0.8) as usize)
}

/// Refuse up front a mesh whose hierarchy cannot fit the memory budget
/// even at [`radiosity::MIN_LINKS_PER_ELEMENT`] links per element, saying
/// the estimate and what to change; else the most links that fit.
fn memory_check(elements: usize, options: &RadiosityOptions) -> anyhow::Result<usize> {
    let Some(budget) = memory_budget(options) else {
        return Ok(radiosity::HierarchyOptions::default().max_links);
    };
    let floor = radiosity::estimate_bytes(elements, radiosity::MIN_LINKS_PER_ELEMENT * elements);
    anyhow::ensure!(
        floor <= budget,
        "the mesh has {elements} elements; solving it hierarchically needs at least {:.0} MB \
         (the cluster tree and at least {} links per element of {} bytes), over the {:.0} MB \
         budget: raise --max-patch-area or the scene's patch_area (now {} m^2), or \
         --max-memory-mb if the machine has more",
        floor as f64 / 1e6,
        radiosity::MIN_LINKS_PER_ELEMENT,
        radiosity::LINK_BYTES,
        budget as f64 / 1e6,
        options.patch_area(),
    );
    Ok((budget - radiosity::estimate_bytes(elements, 0)) / radiosity::LINK_BYTES)
}

/// Patches and elements of `showcase` meshed with `options`, before
/// adaptive refinement: what a solve's cost grows with. An error says why
/// the scene has nothing to solve (no surface, nothing emitting light).
pub fn mesh_size(
    showcase: &Showcase,
    options: &RadiosityOptions,
) -> anyhow::Result<(usize, usize)> {
    let options = &options.for_scene(showcase);
    let all = SceneGeometry::build(showcase, &ObjectFilter::All).context("building geometry")?;
    let mesh = RadiosityMesh::build(showcase, &all, &options.mesh()).context("meshing")?;
    let lights: Vec<_> = showcase.lights.iter().map(|l| l.light.clone()).collect();
    check_solvable(&mesh, &lights)?;
    Ok((mesh.patches.len(), mesh.elements.len()))
}

/// Refuse a scene whose radiosity is zero for want of input: no surface
/// to solve, or nothing that emits light (no positive `Ke`, no light),
/// which is what an OBJ without its material library looks like.
fn check_solvable(mesh: &RadiosityMesh, lights: &[showcase_proto::Light]) -> anyhow::Result<()> {
    anyhow::ensure!(
        !mesh.patches.is_empty(),
        "the scene has no surface to solve: no object has a triangle of non-zero area"
    );
    let emits = mesh.elements.iter().any(|e| e.emission.max_element() > 0.0);
    anyhow::ensure!(
        emits || !lights.is_empty(),
        "nothing in the scene emits light (no material has a positive Ke and there is no \
         light), so its radiosity is zero everywhere"
    );
    Ok(())
}

/// A file-name-safe version of an object or device name.
fn file_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `showcase-master radiosity`: solve `scene` (any scene
/// [`crate::scene_file::load_any`] reads) and write
/// `solution.ply` (B0 per vertex of the output mesh, by a final gather
/// from the solution with the ambient estimate of the energy still unshot
/// at the threshold), `irradiance_map_<projector>.pfm` (linear
/// drive), `light_map_<object>.ply` per virtual object and `summary.json`
/// into `out`.
pub fn run_radiosity(
    scene: &Path,
    out: &Path,
    options: &RadiosityOptions,
) -> anyhow::Result<Summary> {
    run_radiosity_on(scene, out, options, FormFactorDevice::Cpu)
}

/// [`run_radiosity`] with the hemi-cube item buffers made on `device`
/// (`--form-factors cpu|gpu`).
pub fn run_radiosity_on(
    scene: &Path,
    out: &Path,
    options: &RadiosityOptions,
    device: FormFactorDevice,
) -> anyhow::Result<Summary> {
    let showcase = crate::scene_file::load_any(scene)?;
    run_radiosity_scene(
        &showcase,
        &scene.display().to_string(),
        out,
        options,
        device,
    )
}

/// [`run_radiosity_on`] for a scene in memory, named `label` in errors.
pub fn run_radiosity_scene(
    showcase: &Showcase,
    label: &str,
    out: &Path,
    options: &RadiosityOptions,
    device: FormFactorDevice,
) -> anyhow::Result<Summary> {
    let start = Instant::now();
    let solved = solve_showcase_on(showcase, options, device).with_context(|| label.to_string())?;
    let solve_seconds = start.elapsed().as_secs_f64();
    let mut maps = Vec::new();
    if let Some(b2) = &solved.b2_vertices {
        for i in 0..showcase.projectors.len() {
            maps.push(
                irradiance_map(&solved.mesh, &solved.real, b2, &showcase.projectors, i)
                    .with_context(|| format!("projector {}", showcase.projectors[i].name))?,
            );
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let solution = out.join("solution.ply");
    let whole = vertex_mesh_from_vertices(&solved.output_mesh, &solved.b0_vertices, |_| true);
    std::fs::write(&solution, export::ply_ascii(&whole))
        .with_context(|| format!("writing {}", solution.display()))?;
    let mut irradiance_maps = Vec::new();
    for (p, map) in showcase.projectors.iter().zip(&maps) {
        let path = out.join(format!("irradiance_map_{}.pfm", file_name(&p.name)));
        std::fs::write(&path, crate::pfm::encode_pfm(&map.drive))
            .with_context(|| format!("writing {}", path.display()))?;
        irradiance_maps.push(path);
    }
    let mut light_maps = Vec::new();
    for (i, o) in showcase.objects.iter().enumerate() {
        if o.kind != ObjectKind::Virtual {
            continue;
        }
        let m = vertex_mesh_from_vertices(&solved.output_mesh, &solved.b0_vertices, |e| {
            e.object as usize == i
        });
        let path = out.join(format!("light_map_{}.ply", file_name(&o.name)));
        std::fs::write(&path, export::ply_ascii(&m))
            .with_context(|| format!("writing {}", path.display()))?;
        light_maps.push(path);
    }
    let summary = Summary {
        solver: match solved.solver {
            Solver::Hierarchical => "hierarchical",
            _ => "progressive",
        },
        links: solved.links,
        complete: solved.complete,
        patches: solved.mesh.patches.len(),
        elements: solved.mesh.elements.len(),
        shots: solved.shots
            + solved
                .augmented
                .as_ref()
                .map_or(0, |a| a.shots.iter().sum()),
        unshot_fraction: solved.unshot_fraction,
        seconds,
        solve_seconds,
        solution,
        irradiance_maps,
        light_maps,
        clipped_fractions: maps.iter().map(|m| m.clipped_fraction()).collect(),
        clipped_elements: solved.augmented.as_ref().map_or(0, |a| a.clipped_elements),
        b3_b0_deviation_rgb: solved.augmented.as_ref().map(|a| a.b3_b0_deviation_rgb),
        convergence: solved.convergence,
    };
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::{BadFormFactorDevice, FormFactorDevice, RadiosityOptions, mesh_size};
    use std::path::Path;

    #[test]
    fn a_scene_meshes_with_its_own_patch_area_unless_the_command_names_one() {
        let figure3 = crate::scene_file::load_any(Path::new("builtin:figure3")).unwrap();
        assert_eq!(figure3.patch_area, Some(0.0025));
        let scene = RadiosityOptions::default();
        let given = RadiosityOptions {
            max_patch_area: Some(0.01),
            ..Default::default()
        };
        assert_eq!(scene.for_scene(&figure3).patch_area(), 0.0025);
        assert_eq!(given.for_scene(&figure3).patch_area(), 0.01);
        // Every 0.01 m^2 patch of the box becomes four.
        let (_, fine) = mesh_size(&figure3, &scene).unwrap();
        let (_, coarse) = mesh_size(&figure3, &given).unwrap();
        assert_eq!((fine, coarse), (3840, 960));
    }

    #[test]
    fn form_factor_devices_parse_and_refuse_others_by_name() {
        assert_eq!("cpu".parse(), Ok(FormFactorDevice::Cpu));
        assert_eq!("gpu".parse(), Ok(FormFactorDevice::Gpu));
        for bad in ["GPU", "", "cuda"] {
            let e = bad.parse::<FormFactorDevice>().unwrap_err();
            assert_eq!(e, BadFormFactorDevice(bad.to_string()));
            assert!(e.to_string().contains(&format!("{bad:?}")), "{e}");
        }
    }
}
