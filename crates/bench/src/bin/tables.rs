//! `tables`: the thesis' Appendix B tables (cuMat benchmarks B.1-B.4, cuboid B.5/B.6) reproduced on this
//! machine with gpumat, side by side with the unfused baseline, Eigen, numpy and the STREAM
//! triad bandwidth, and the adjoint's Table 5.2 (forward / cost / backward per step, memory).
//!
//! ```sh
//! cargo run --release -p bench --bin tables -- [--json] [--quick]
//! ```
//!
//! Markdown goes to stdout, or to stderr with `--json`, which prints exactly one JSON object
//! on stdout (schema: `docs/interface.md`, "Benchmark tables").

use bench::machine::{self, Machine};
use bench::peers::Peers;
use bench::report::{col, markdown_table, Fmt};
use bench::timing::Policy;
use bench::{
    progress, stream, table_adjoint, table_advect, table_bsr, table_cuboid, table_diagnose, table_hidden,
    table_lincomb, table_scaling, table_sparse, table_step_peer, thesis, Ctx,
};
use clap::Parser;
use serde::Serialize;
use serde_json::Value;
use std::io::Write;

/// Reproduces the thesis' Tables B.1-B.6 and 5.2 on this machine, and our own Tables D (diagnosis
/// speed) and H (the diagnosis on the independent hidden-effect cases).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Args {
    /// Print one JSON object on stdout (markdown goes to stderr).
    #[arg(long)]
    json: bool,
    /// Reduced sizes and repetitions (about a minute).
    #[arg(long)]
    quick: bool,
    /// Only these tables (comma-separated, e.g. `B.2,B.3`).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Do not build or run the Eigen and numpy peers (their columns are null).
    #[arg(long)]
    no_peers: bool,
    /// Also write the markdown report to this file.
    #[arg(long, value_name = "PATH")]
    markdown: Option<std::path::PathBuf>,
    /// Table H from the rows of an earlier `--json` report instead of running the diagnoses
    /// (to redraw its markdown and picture).
    #[arg(long, value_name = "REPORT.json")]
    hidden_rows: Option<std::path::PathBuf>,
    /// Table H: diagnose only the cases whose names start with one of these prefixes
    /// (comma-separated, e.g. `corotation/,complete-corotation/`); with `--hidden-rows`, their
    /// rows replace those of the earlier report (new cases join in `cases.json`'s order).
    #[arg(long, value_name = "PREFIXES", value_delimiter = ',')]
    hidden_cases: Vec<String>,
    /// Write the pictures of the tables into this folder: B.1, B.2 and scaling as PNG with an
    /// SVG twin (`b1_time_vs_n.png`, `b2_time_vs_k.png`, `scaling.png`), Table H as
    /// `detection_curves.svg`.
    #[arg(long, value_name = "DIR")]
    figures: Option<std::path::PathBuf>,
    /// Only draw the pictures of an earlier `--json` report into the `--figures` folder
    /// (nothing is measured).
    #[arg(long, value_name = "REPORT.json", requires = "figures")]
    figures_from: Option<std::path::PathBuf>,
    /// Internal: the child process of Table 5.2's memory run (observations CSV).
    #[arg(long, hide = true, requires = "adjoint_memory_steps")]
    adjoint_memory_child: Option<std::path::PathBuf>,
    /// Internal: steps of Table 5.2's memory run.
    #[arg(long, hide = true)]
    adjoint_memory_steps: Option<usize>,
}

/// The `tables` object, rows in field order (a `serde_json::Map` would sort the keys).
#[derive(Debug, Serialize)]
struct Tables {
    #[serde(rename = "B.1", skip_serializing_if = "Option::is_none")]
    b1: Option<Vec<table_lincomb::LincombRow>>,
    #[serde(rename = "B.2", skip_serializing_if = "Option::is_none")]
    b2: Option<Vec<table_lincomb::LincombRow>>,
    #[serde(rename = "B.2-dram", skip_serializing_if = "Option::is_none")]
    b2_dram: Option<Vec<table_lincomb::LincombRow>>,
    #[serde(rename = "B.3", skip_serializing_if = "Option::is_none")]
    b3: Option<Vec<table_sparse::SpmvRow>>,
    #[serde(rename = "B.3-bsr", skip_serializing_if = "Option::is_none")]
    b3_bsr: Option<Vec<table_bsr::Row>>,
    #[serde(rename = "B.4", skip_serializing_if = "Option::is_none")]
    b4: Option<Vec<table_sparse::CgRow>>,
    #[serde(rename = "B.5", skip_serializing_if = "Option::is_none")]
    b5: Option<Vec<table_cuboid::CuboidRow>>,
    #[serde(rename = "B.6", skip_serializing_if = "Option::is_none")]
    b6: Option<Vec<table_cuboid::CuboidRow>>,
    #[serde(rename = "4.4", skip_serializing_if = "Option::is_none")]
    t44: Option<Vec<table_advect::Row>>,
    #[serde(rename = "step-peer", skip_serializing_if = "Option::is_none")]
    step_peer: Option<Vec<table_step_peer::Row>>,
    #[serde(rename = "scaling", skip_serializing_if = "Option::is_none")]
    scaling: Option<Vec<table_scaling::Row>>,
    #[serde(rename = "5.2", skip_serializing_if = "Option::is_none")]
    t52: Option<Vec<table_adjoint::Row>>,
    #[serde(rename = "D", skip_serializing_if = "Option::is_none")]
    d: Option<Vec<table_diagnose::Row>>,
    #[serde(rename = "H", skip_serializing_if = "Option::is_none")]
    h: Option<Vec<table_hidden::Row>>,
}

/// Draws the B.1, B.2 and scaling pictures into `dir`, or exits with the error.
fn write_figures(tables: &serde_json::Map<String, Value>, dir: &std::path::Path) {
    match bench::figures::write(tables, dir) {
        Ok(paths) => paths
            .iter()
            .for_each(|p| progress(&format!("wrote {}", p.display()))),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}

/// The `tables` object of an earlier `--json` report, or a one-line error.
fn tables_of_report(path: &std::path::Path) -> Result<serde_json::Map<String, Value>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| format!("{}: not JSON: {e}", path.display()))?;
    match v.get("tables") {
        Some(Value::Object(m)) => Ok(m.clone()),
        _ => Err(format!(
            "{}: no \"tables\" object (not a `tables --json` report)",
            path.display()
        )),
    }
}

/// The JSON report: exactly this object is printed with `--json`.
#[derive(Debug, Serialize)]
struct Report<'a> {
    machine: &'a Machine,
    tables: &'a Tables,
    targets: &'a Value,
}

fn markdown(machine: &Machine, tables: &serde_json::Map<String, Value>, targets: &Value) -> String {
    let mut s = String::from("# Thesis Appendix B (cuMat benchmarks) reproduced with gpumat\n\n");
    s.push_str(&format!(
        "- machine: {} ({} logical cores, {} rayon threads, {}), {}, mode {}\n",
        machine.cpu,
        machine.cores,
        machine.rayon_threads,
        machine.llc.as_deref().unwrap_or("LLC unknown"),
        machine.date,
        machine.mode
    ));
    s.push_str(&format!(
        "- STREAM triad (rayon, all cores, {} f32 per array): **{:.1} GB/s**, the best of the samples \
         taken before, between and after the tables ({:.1?}); each table's fractions use the better \
         of the two samples around it (its rows' `stream_triad_gbs`)\n",
        machine.stream_triad_len, machine.stream_triad_gbs, machine.stream_triad_runs_gbs
    ));
    s.push_str(&format!("- timing: {}\n", machine.timing));
    s.push_str(&format!(
        "- load average (1/5/15 min) at start / end: {} / {}\n",
        machine.load_average[0].as_deref().unwrap_or("?"),
        machine.load_average[1].as_deref().unwrap_or("?")
    ));
    s.push_str(&format!("- bytes: {}\n", machine.bytes));
    s.push_str(&format!("- gpumat: {}\n", machine.gpumat_build));
    match &machine.eigen {
        Some(e) => s.push_str(&format!(
            "- Eigen {}: {} `{}`\n",
            e.get("eigen").map_or("?", String::as_str),
            e.get("compiler").map_or("?", String::as_str),
            e.get("flags").map_or("?", String::as_str)
        )),
        None => s.push_str("- Eigen: not available\n"),
    }
    s.push_str(&format!(
        "- numpy: {}\n",
        machine.numpy.as_deref().unwrap_or("not available")
    ));
    s.push_str(&format!(
        "- scikit-fem: {}\n",
        machine.skfem.as_deref().unwrap_or("not available")
    ));
    s.push_str(&format!("- thesis columns: {}\n", machine.thesis_hardware));
    for n in &machine.notes {
        s.push_str(&format!("- note: {n}\n"));
    }
    s.push_str(
        "\n## Targets (reported, not asserted)\n\n| target | value | goal | met |\n|---|---:|---:|---:|\n",
    );
    if let Some(obj) = targets.as_object() {
        for t in obj.values() {
            let v = t["value"]
                .as_f64()
                .map_or("not available".to_string(), |v| format!("{v:.2}"));
            let met = t["met"]
                .as_bool()
                .map_or("not available", |m| if m { "yes" } else { "no" });
            s.push_str(&format!(
                "| {} | {v} | {} {} | {met} |\n",
                t["what"].as_str().unwrap_or(""),
                t["cmp"].as_str().unwrap_or(">="),
                t["goal"]
            ));
        }
    }
    s.push_str("\n## Tables\n\n");
    let rows = |id: &str| -> Vec<Value> {
        tables
            .get(id)
            .and_then(|v| v.as_array())
            .cloned()
            .unwrap_or_default()
    };
    if tables.contains_key("B.1") {
        s.push_str(&markdown_table(
            "Table B.1: linear combination of k = 2 f32 vectors of length n",
            "gpumat: one fused `assign`; unfused: one pass per term; times per run.",
            &rows("B.1"),
            &table_lincomb::columns(col("n", "n", Fmt::Plain)),
        ));
    }
    if tables.contains_key("B.2") {
        s.push_str(&markdown_table(
            "Table B.2: linear combination of k f32 vectors, n = 10^6",
            "",
            &rows("B.2"),
            &table_lincomb::columns(col("k", "k", Fmt::Plain)),
        ));
    }
    if tables.contains_key("B.2-dram") {
        s.push_str(&markdown_table(
            "Table B.2-dram: linear combination of k f32 vectors, n = 10^7 (every vector from memory)",
            "B.2 at ten times the length: 40 MB per vector, so each pass of the unfused variant streams \
             from memory and the traffic ratio is the ceiling of what fusion can give.",
            &rows("B.2-dram"),
            &table_lincomb::columns(col("k", "k", Fmt::Plain)),
        ));
    }
    if tables.contains_key("B.3") {
        s.push_str(&markdown_table(
            "Table B.3: CSR SpMV, 5-point 2D Poisson matrix of a g x g grid, f32",
            "bytes = values + column indices + row pointers + x + y, as each side stores them \
             (gpumat: `SparsityPattern`'s index types; Eigen: 4-byte int); each side's GB/s counts \
             its own bytes. scipy: `csr_matrix @ x` (f32, one thread).",
            &rows("B.3"),
            &table_sparse::b3_columns(),
        ));
    }
    if tables.contains_key("B.3-bsr") {
        s.push_str(&table_bsr::markdown(&rows("B.3-bsr")));
    }
    if tables.contains_key("B.4") {
        s.push_str(&markdown_table(
            "Table B.4: CG on 2D diffusion (g x g grid), f32, Jacobi, tolerance 1e-4, x0 = 0",
            "Times are preconditioner setup + solve; per-iteration = total / iterations; iterations = \
             updates of x for both (Eigen's own `iterations()` is one less: it leaves out the converging \
             one). gpumat: `Jacobi` + `gpumat::cg`; Eigen: `ConjugateGradient<RowMajor, Lower|Upper, \
             DiagonalPreconditioner>`; scipy: `scipy.sparse.linalg.cg` with a Jacobi `LinearOperator`, \
             iterations counted by its callback.",
            &rows("B.4"),
            &table_sparse::b4_columns(),
        ));
    }
    for (id, what) in [
        ("B.5", "held at one end (Nitsche / hard Dirichlet)"),
        ("B.6", "falling on the ground"),
    ] {
        if tables.contains_key(id) {
            s.push_str(&markdown_table(
                &format!("Table {id}: the cuboid {what}, grid vs 6 tets per cell, corotation on"),
                "Cells of size 1/(2r); f64; CG with block-Jacobi, relative tolerance 1e-6, warm start \
                 u + dt v; times per step averaged over the run. K = rotations + stiffness values (the \
                 thesis' matrix assembly; the grid's one pass over cells and rows also computes K u, the \
                 corotation and body forces, all blocks of A and most of b there, and its steps \
                 put the stiffness values into A without storing K); asm = K + the rest of the \
                 Newmark A and b (the grid: adding dt f to b). \
                 IC0 / RC: the same grid steps with the modified block IC(0) preconditioner (every step) \
                 / with the rest-state Cholesky factor (nested dissection, refactored after a step of \
                 more than 25 iterations); their CG ms leave out the factorizations, factor ms = all \
                 factorization seconds / steps, facts = factorizations in the run. \
                 Thesis columns: GTX 1060, f32.",
                &rows(id),
                &table_cuboid::columns(),
            ));
        }
    }
    if tables.contains_key("4.4") {
        s.push_str(&table_advect::markdown(&rows("4.4")));
    }
    if tables.contains_key("step-peer") {
        s.push_str(&table_step_peer::markdown(&rows("step-peer")));
    }
    if tables.contains_key("scaling") {
        s.push_str(&table_scaling::markdown(&rows("scaling")));
    }
    if tables.contains_key("D") {
        s.push_str(&table_diagnose::markdown(&rows("D")));
    }
    if tables.contains_key("5.2") {
        s.push_str(&table_adjoint::markdown(&rows("5.2")));
    }
    if tables.contains_key("H") {
        s.push_str(&table_hidden::markdown(&rows("H")));
    }
    s
}

impl Tables {
    /// The measured tables as JSON rows, by table id.
    fn values(&self) -> serde_json::Map<String, Value> {
        match serde_json::to_value(self).expect("tables serialize") {
            Value::Object(m) => m,
            _ => unreachable!("a struct serializes to an object"),
        }
    }
}

/// The notes every report carries (how the peers were built and run, what the columns mean).
fn notes() -> Vec<String> {
    vec![
        "Eigen is built with -fopenmp: its SpMV (B.3) and the SpMV inside its CG (B.4, Lower|Upper) \
         run on all cores; its dense vector expressions (B.1, B.2, CG vector updates) are single-threaded \
         (Eigen does not parallelise coefficient-wise operations). gpumat runs every pass on rayon."
            .to_string(),
        "B.1/B.2 Eigen evaluates into a preallocated vector (`d.noalias() = ...`), not `.eval()` into a \
         fresh one as the thesis' code did; numpy evaluates `a0*v0 + a1*v1 + ...` with temporaries."
            .to_string(),
        "B.3 omits the thesis' g = 10000 row (10^8 unknowns; too large for this machine's memory budget)."
            .to_string(),
        "fraction_of_stream above 1 means the working set is partly cache-resident (B.1/B.2 at \
         n <= 1e6: 4 MB per vector; B.2's k = 10 case moves 44 MB); the DRAM-bound rows are B.1 at \
         n >= 1e7, B.3 and B.4 at g = 1000."
            .to_string(),
        "the B.2 fused-speedup goal (>= 3) is above the traffic ratio of the two variants (29/11 = 2.64 \
         at k = 10), the most fusion can give to a bandwidth-bound CPU loop; the unfused passes also \
         find their destination in cache, so the measured speedup is lower still. The thesis' large GPU \
         gap came from per-call cuBLAS launch/synchronisation costs, which a CPU loop does not have."
            .to_string(),
        thesis::GPU_TIMING_CAVEAT.to_string(),
    ]
}

fn main() {
    let args = Args::parse();
    if let (Some(csv), Some(steps)) = (&args.adjoint_memory_child, args.adjoint_memory_steps) {
        if let Err(e) = table_adjoint::memory_child(csv, steps) {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
        return;
    }
    if let (Some(report), Some(dir)) = (&args.figures_from, &args.figures) {
        match tables_of_report(report) {
            Ok(tables) => write_figures(&tables, dir),
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
        }
        return;
    }
    let wanted = |id: &str| args.only.is_empty() || args.only.iter().any(|o| o.eq_ignore_ascii_case(id));
    let policy = if args.quick {
        Policy::quick()
    } else {
        Policy::full()
    };
    let load_start = machine::load_average();

    progress("building / detecting peers (Eigen, numpy, scikit-fem)");
    let peers = Peers::detect(!args.no_peers);
    progress("STREAM triad");
    let stream_policy = Policy {
        min_samples: 10,
        max_samples: 40,
        ..policy
    };
    // The triad is sampled before and after every table: the bandwidth a shared host gives
    // varies over time, so each table is compared with the better of the two samples around
    // it (`stream_triad_gbs` of its rows); the machine's figure is the best sample of all.
    let mut triad = stream::Triad::new(stream::DEFAULT_LEN);
    let mut stream_runs = vec![triad.gbs(&stream_policy).0];
    progress(&format!("STREAM triad: {:.1} GB/s", stream_runs[0]));
    let mut ctx = Ctx {
        policy,
        peers,
        stream_gbs: stream_runs[0],
        quick: args.quick,
    };
    let mut resample = |runs: &mut Vec<f64>| -> f64 {
        let before = runs.last().copied().unwrap_or(0.0);
        let after = triad.gbs(&stream_policy).0;
        runs.push(after);
        before.max(after)
    };

    let mut b1 = wanted("B.1").then(|| table_lincomb::table_b1(&mut ctx));
    if let Some(rows) = &mut b1 {
        let s = resample(&mut stream_runs);
        rows.iter_mut().for_each(|r| r.set_stream(s));
    }
    let mut b2 = wanted("B.2").then(|| table_lincomb::table_b2(&mut ctx));
    if let Some(rows) = &mut b2 {
        let s = resample(&mut stream_runs);
        rows.iter_mut().for_each(|r| r.set_stream(s));
    }
    let mut b2_dram = wanted("B.2-dram").then(|| table_lincomb::table_b2_dram(&mut ctx));
    if let Some(rows) = &mut b2_dram {
        let s = resample(&mut stream_runs);
        rows.iter_mut().for_each(|r| r.set_stream(s));
    }
    let mut b3 = wanted("B.3").then(|| table_sparse::table_b3(&mut ctx));
    if let Some(rows) = &mut b3 {
        let s = resample(&mut stream_runs);
        rows.iter_mut().for_each(|r| r.set_stream(s));
    }
    let b3_bsr = wanted("B.3-bsr").then(|| table_bsr::table(&mut ctx));
    let mut b4 = wanted("B.4").then(|| table_sparse::table_b4(&mut ctx));
    if let Some(rows) = &mut b4 {
        let s = resample(&mut stream_runs);
        rows.iter_mut().for_each(|r| r.set_stream(s));
    }
    let b5 = wanted("B.5").then(|| table_cuboid::table(false, args.quick));
    let b6 = wanted("B.6").then(|| table_cuboid::table(true, args.quick));
    let t44 = wanted("4.4").then(|| table_advect::table(args.quick, &mut ctx.peers.notes));
    let step_peer = wanted("step-peer").then(|| table_step_peer::table(&mut ctx));
    let scaling = wanted("scaling").then(|| table_scaling::table(args.quick, &mut ctx.peers.notes));
    let (t52, mut notes52) = match wanted("5.2").then(|| table_adjoint::table(args.quick)) {
        Some((rows, notes)) => (Some(rows), notes),
        None => (None, Vec::new()),
    };
    let d = wanted("D").then(|| table_diagnose::table(args.quick));
    let h = wanted("H").then(|| {
        let earlier = args.hidden_rows.as_ref().map(|path| {
            table_hidden::rows_from_report(path).unwrap_or_else(|e| {
                eprintln!("error: {e}");
                std::process::exit(1);
            })
        });
        match earlier {
            Some(rows) if args.hidden_cases.is_empty() => rows,
            earlier => {
                let fresh = table_hidden::table(args.quick, &args.hidden_cases);
                table_hidden::merge(earlier.unwrap_or_default(), fresh)
            }
        }
    });
    if let (Some(rows), Some(dir)) = (&h, &args.figures) {
        let rows: Vec<Value> = rows
            .iter()
            .map(|r| serde_json::to_value(r).expect("row"))
            .collect();
        let path = dir.join("detection_curves.svg");
        if let Err(e) = std::fs::write(&path, table_hidden::svg(&rows)) {
            eprintln!("error: cannot write {}: {e}", path.display());
            std::process::exit(1);
        }
    }
    let typed = Tables {
        b1,
        b2,
        b2_dram,
        b3,
        b3_bsr,
        b4,
        b5,
        b6,
        t44,
        step_peer,
        scaling,
        t52,
        d,
        h,
    };
    let stream_gbs = stream_runs.iter().copied().fold(0.0, f64::max);
    progress(&format!("STREAM triad samples {stream_runs:.1?} GB/s"));
    let tables = typed.values();
    if let Some(dir) = &args.figures {
        write_figures(&tables, dir);
    }

    let mut notes = notes();
    if args.quick {
        notes.push("quick mode: B.1 stops at n = 1e7, B.4 at g = 300".into());
    }
    notes.append(&mut ctx.peers.notes);
    notes.append(&mut notes52);
    let machine = Machine {
        cpu: machine::cpu_name(),
        cores: machine::cores(),
        rayon_threads: rayon::current_num_threads(),
        llc: machine::llc(),
        date: machine::utc_now(),
        mode: if args.quick { "quick" } else { "full" }.into(),
        stream_triad_gbs: stream_gbs,
        stream_triad_runs_gbs: stream_runs,
        stream_triad_len: stream::DEFAULT_LEN,
        timing: policy.describe(),
        bytes: "bytes = compulsory traffic of one run (every array read or written once; write-allocate \
                not counted, as in STREAM); GB/s = 1e9 bytes/s; fraction_of_stream = GB/s / stream_triad_gbs"
            .into(),
        gpumat_build: machine::gpumat_build(),
        eigen: ctx.peers.eigen.as_ref().map(|e| e.info.clone()),
        numpy: ctx.peers.numpy.as_ref().map(|n| n.version.clone()),
        skfem: ctx.peers.skfem.as_ref().map(|n| n.version.clone()),
        thesis_hardware: thesis::HARDWARE.into(),
        load_average: [load_start, machine::load_average()],
        notes,
    };
    let targets = bench::targets::targets(&tables);
    let md = markdown(&machine, &tables, &targets);
    if let Some(path) = &args.markdown {
        if let Err(e) = std::fs::write(path, &md) {
            eprintln!("error: cannot write {}: {e}", path.display());
            std::process::exit(1);
        }
    }
    if args.json {
        eprint!("{md}");
        let out = Report {
            machine: &machine,
            tables: &typed,
            targets: &targets,
        };
        let mut stdout = std::io::stdout().lock();
        serde_json::to_writer_pretty(&mut stdout, &out).expect("write JSON");
        writeln!(stdout).expect("write JSON");
    } else {
        print!("{md}");
    }
}
