//! `tables`: the thesis' Appendix B tables (cuMat benchmarks B.1-B.4) reproduced on this
//! machine with gpumat, side by side with the unfused baseline, Eigen, numpy and the STREAM
//! triad bandwidth.
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
use bench::{progress, stream, table_lincomb, table_sparse, thesis, Ctx};
use clap::Parser;
use serde::Serialize;
use serde_json::{json, Value};
use std::io::Write;

/// Reproduces the thesis' Tables B.1-B.4 on this machine.
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
}

/// The `tables` object, rows in field order (a `serde_json::Map` would sort the keys).
#[derive(Debug, Serialize)]
struct Tables {
    #[serde(rename = "B.1", skip_serializing_if = "Option::is_none")]
    b1: Option<Vec<table_lincomb::LincombRow>>,
    #[serde(rename = "B.2", skip_serializing_if = "Option::is_none")]
    b2: Option<Vec<table_lincomb::LincombRow>>,
    #[serde(rename = "B.3", skip_serializing_if = "Option::is_none")]
    b3: Option<Vec<table_sparse::SpmvRow>>,
    #[serde(rename = "B.4", skip_serializing_if = "Option::is_none")]
    b4: Option<Vec<table_sparse::CgRow>>,
}

/// The JSON report: exactly this object is printed with `--json`.
#[derive(Debug, Serialize)]
struct Report<'a> {
    machine: &'a Machine,
    tables: &'a Tables,
    targets: &'a Value,
}

fn to_values<T: Serialize>(rows: &[T]) -> Vec<Value> {
    rows.iter()
        .map(|r| serde_json::to_value(r).expect("rows serialize"))
        .collect()
}

/// The headline ratios (reported, never asserted).
fn targets(tables: &serde_json::Map<String, Value>) -> Value {
    let find = |t: &str, key: &str, val: u64, field: &str| -> Value {
        tables
            .get(t)
            .and_then(|rows| rows.as_array())
            .and_then(|rows| {
                rows.iter()
                    .find(|r| r.get(key).and_then(Value::as_u64) == Some(val))
            })
            .and_then(|r| r.get(field).cloned())
            .unwrap_or(Value::Null)
    };
    let last_grid = tables
        .get("B.4")
        .and_then(|r| r.as_array())
        .and_then(|r| r.last())
        .and_then(|r| r.get("grid"))
        .and_then(Value::as_u64)
        .unwrap_or(1000);
    let target = |value: Value, goal: f64, what: &str| {
        let met = value.as_f64().map(|v| v >= goal);
        json!({"value": value, "goal": goal, "met": met, "what": what})
    };
    json!({
        "lincomb_k10_fraction_of_stream": target(find("B.2", "k", 10, "fraction_of_stream"), 0.7,
            "B.2 k=10, n=1e6: fused gpumat bandwidth / STREAM triad"),
        "lincomb_k10_fused_speedup": target(find("B.2", "k", 10, "fused_speedup"), 3.0,
            "B.2 k=10, n=1e6: unfused time / fused time (memory traffic ratio 29/11 = 2.64)"),
        "spmv_g1000_fraction_of_stream": target(find("B.3", "grid", 1000, "fraction_of_stream"), 0.6,
            "B.3 g=1000: gpumat SpMV bandwidth / STREAM triad"),
        "cg_per_iteration_speedup_vs_eigen": target(
            find("B.4", "grid", last_grid, "per_iteration_speedup_vs_eigen"), 1.0,
            &format!("B.4 g={last_grid}: Eigen time per iteration / gpumat time per iteration")),
    })
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
        "- STREAM triad (rayon, all cores, {} f32 per array): **{:.1} GB/s**\n",
        machine.stream_triad_len, machine.stream_triad_gbs
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
                "| {} | {v} | >= {} | {met} |\n",
                t["what"].as_str().unwrap_or(""),
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
    if tables.contains_key("B.3") {
        s.push_str(&markdown_table(
            "Table B.3: CSR SpMV, 5-point 2D Poisson matrix of a g x g grid, f32",
            "bytes = values + column indices + row pointers + x + y; gpumat's indices are 8 bytes \
             (usize), Eigen's 4 (int), each side's GB/s counts its own bytes.",
            &rows("B.3"),
            &table_sparse::b3_columns(),
        ));
    }
    if tables.contains_key("B.4") {
        s.push_str(&markdown_table(
            "Table B.4: CG on 2D diffusion (g x g grid), f32, Jacobi, tolerance 1e-4, x0 = 0",
            "Times are preconditioner setup + solve; per-iteration = total / iterations.",
            &rows("B.4"),
            &table_sparse::b4_columns(),
        ));
    }
    s
}

fn main() {
    let args = Args::parse();
    let wanted = |id: &str| args.only.is_empty() || args.only.iter().any(|o| o.eq_ignore_ascii_case(id));
    let policy = if args.quick {
        Policy::quick()
    } else {
        Policy::full()
    };
    let load_start = machine::load_average();

    progress("building / detecting peers (Eigen, numpy)");
    let peers = Peers::detect(!args.no_peers);
    progress("STREAM triad");
    let stream_policy = Policy {
        min_samples: 10,
        max_samples: 40,
        ..policy
    };
    let (stream_gbs, _) = stream::triad_gbs(stream::DEFAULT_LEN, &stream_policy);
    progress(&format!("STREAM triad: {stream_gbs:.1} GB/s"));
    let mut ctx = Ctx {
        policy,
        peers,
        stream_gbs,
        quick: args.quick,
    };

    let typed = Tables {
        b1: wanted("B.1").then(|| table_lincomb::table_b1(&mut ctx)),
        b2: wanted("B.2").then(|| table_lincomb::table_b2(&mut ctx)),
        b3: wanted("B.3").then(|| table_sparse::table_b3(&mut ctx)),
        b4: wanted("B.4").then(|| table_sparse::table_b4(&mut ctx)),
    };
    let mut tables = serde_json::Map::new();
    if let Some(r) = &typed.b1 {
        tables.insert("B.1".into(), Value::Array(to_values(r)));
    }
    if let Some(r) = &typed.b2 {
        tables.insert("B.2".into(), Value::Array(to_values(r)));
    }
    if let Some(r) = &typed.b3 {
        tables.insert("B.3".into(), Value::Array(to_values(r)));
    }
    if let Some(r) = &typed.b4 {
        tables.insert("B.4".into(), Value::Array(to_values(r)));
    }

    let mut notes = vec![
        "Eigen is built with -fopenmp: its SpMV (B.3) and the SpMV inside its CG (B.4, Lower|Upper) \
         run on all cores; its dense vector expressions (B.1, B.2, CG vector updates) are single-threaded \
         (Eigen does not parallelise coefficient-wise operations). gpumat runs every pass on rayon."
            .to_string(),
        "B.1/B.2 Eigen evaluates into a preallocated vector (`d.noalias() = ...`), not `.eval()` into a \
         fresh one as the thesis' code did; numpy evaluates `a0*v0 + a1*v1 + ...` with temporaries."
            .to_string(),
        "B.3 omits the thesis' g = 10000 row (10^8 unknowns; too large for this machine's memory budget)."
            .to_string(),
        thesis::GPU_TIMING_CAVEAT.to_string(),
    ];
    if args.quick {
        notes.push("quick mode: B.1 stops at n = 1e7, B.4 at g = 300".into());
    }
    notes.append(&mut ctx.peers.notes);
    let machine = Machine {
        cpu: machine::cpu_name(),
        cores: machine::cores(),
        rayon_threads: rayon::current_num_threads(),
        llc: machine::llc(),
        date: machine::utc_now(),
        mode: if args.quick { "quick" } else { "full" }.into(),
        stream_triad_gbs: stream_gbs,
        stream_triad_len: stream::DEFAULT_LEN,
        timing: policy.describe(),
        bytes: "bytes = compulsory traffic of one run (every array read or written once; write-allocate \
                not counted, as in STREAM); GB/s = 1e9 bytes/s; fraction_of_stream = GB/s / stream_triad_gbs"
            .into(),
        gpumat_build: machine::gpumat_build(),
        eigen: ctx.peers.eigen.as_ref().map(|e| e.info.clone()),
        numpy: ctx.peers.numpy.as_ref().map(|n| n.version.clone()),
        thesis_hardware: thesis::HARDWARE.into(),
        load_average: [load_start, machine::load_average()],
        notes,
    };
    let targets = targets(&tables);
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
