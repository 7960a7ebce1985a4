//! The `pidm` command line: parses arguments, calls [`run`], prints the
//! error chain.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

use pidm::run::shard::ShardSpec;
use pidm::{backend, commands};

/// The exit statuses, shown by `--help`.
const EXIT_STATUS: &str = "\
Exit status:
  0    success
  1    an error: a bad scene, a file that cannot be written, a GPU that fails
  2    a usage error: an unknown command or flag, a missing argument
  3    pidm run: some instance did not finish normally (/maps/status says why)
  130  pidm run stopped by SIGINT (Ctrl-C), 143 by SIGTERM: the finished
       instances stay in the checkpoint beside the output, and the command
       printed on stderr (the same with --resume) continues the run;
       pidm sensitivity and optimize so stopped write nothing";

/// Maps how two-axis piezoelectric impact drives move.
#[derive(Parser, Debug)]
#[command(name = "pidm", version, about, after_help = EXIT_STATUS)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Runs a scene and writes its step-displacement maps to HDF5.
    #[command(after_help = EXIT_STATUS)]
    Run {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Output file [default: results/<scene name>.h5].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Worker threads of the CPU path, from 1 to 4 per core (or 64)
        /// [default: every core].
        #[arg(long, value_parser = pidm::backend::select::thread_count)]
        threads: Option<usize>,
        /// auto: a hardware GPU with f64 when there is one and the run is
        /// estimated to end sooner there (a short probe of its cost against
        /// the GPU's fixed costs and throughput), else the CPU; gpu: any
        /// adapter (lavapipe included), failing when there is none; cpu.
        #[arg(long, value_enum, default_value_t = backend::BackendChoice::Auto)]
        backend: backend::BackendChoice,
        /// Precision [default: f64 where the adapter has it, else f32, on
        /// the GPU; f64 on the CPU]. With --backend cpu, f32 runs the f32
        /// shader's CPU mirror (for checking f32 without a GPU); auto falls
        /// back to the CPU in f64.
        #[arg(long, value_enum)]
        precision: Option<backend::Precision>,
        /// Run only shard K of N (1 <= K <= N) into its own file [default
        /// output: results/<scene name>.shard-K-of-N.h5]; `pidm merge`
        /// joins the shards.
        #[arg(long, value_name = "K/N")]
        shard: Option<ShardSpec>,
        /// Continue an interrupted run from the checkpoint beside its output
        /// file, computing only the instances that are missing.
        #[arg(long)]
        resume: bool,
        /// Instances per chunk: how often the run checkpoints, and what the
        /// pipeline overlaps [default: the backend's choice: 4,096 or 256
        /// per thread on the CPU, one device batch on the GPU: its lanes
        /// four times over, at most 1,048,576 on hardware, 4,096 on a
        /// 2-core software adapter].
        #[arg(long)]
        chunk_size: Option<usize>,
        /// Rerun every instance with a 100 times tighter tolerance and mark
        /// those whose step moves by more than 0.001 um as unconverged
        /// (status 5, map entries 0). Costs about 3 times the run.
        #[arg(long)]
        verify: bool,
        /// Print where the run's wall time went on stderr at the end, one
        /// table: the backend's opening, packing, uploads, dispatches,
        /// readback, reduction, the CPU's part, HDF5 writing, and what no
        /// phase claims (also `PIDM_GPU_PHASES=1`).
        #[arg(long)]
        profile: bool,
        /// How progress is shown on stderr: bar (a bar with an ETA), jsonl
        /// (one JSON object per line: done, total, elapsed_s, eta_s,
        /// instances_per_s; the last has done == total) or none [default:
        /// bar when stderr is a terminal, else none].
        #[arg(long, value_enum)]
        progress: Option<pidm::progress::ProgressMode>,
    },
    /// Calibrates a fit scene's free keys ([fit]) to its measured steps:
    /// writes FIT.json (values, standard errors, correlations, warnings),
    /// FIT.toml (the scene with the fitted values) and FIT.png beside it
    /// (docs/fit.md).
    Fit(commands::FitCommand),
    /// Sobol' indices and the spread of a scene's quantities over
    /// distributions of its keys ([sensitivity]): writes SENS.json and
    /// SENS.png beside it (docs/design.md).
    Sensitivity(commands::SensitivityCommand),
    /// The best values of a scene's free keys ([optimize]) for an objective
    /// under constraints, or the front between two objectives: writes
    /// OPT.json, OPT.toml (the scene at the optimum) and OPT.png
    /// (docs/design.md).
    Optimize(commands::OptimizeCommand),
    /// Joins the shard files of one scene (`pidm run --shard K/N`) into one
    /// map file, the same as a single run's.
    Merge {
        /// The merged output file.
        out: PathBuf,
        /// Every shard file of the run.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
    /// Measures the refinement rule of a scene with [refine] against a
    /// uniform run of its finest grid: the waves replayed on the uniform
    /// file's values for several rule variants (integrated share, label
    /// mismatches, values within the tolerance + 1 %), and with --refined
    /// a refined run's file compared too (its integrated points bit for bit,
    /// its wall time against the uniform run's).
    RefineStudy {
        /// The scene with [refine].
        scene: PathBuf,
        /// Folder of the two runs' files, <name>.uniform.h5 and
        /// <name>.refined.h5.
        #[arg(long, default_value = "results/refine_study")]
        out_dir: PathBuf,
        /// Backend of both runs, as `pidm run --backend`.
        #[arg(long, value_enum, default_value_t = backend::BackendChoice::Auto)]
        backend: backend::BackendChoice,
        /// Reuse this uniform run of the finest grid (the same scene
        /// without [refine] and with (steps - 1) * 2^levels + 1 steps per
        /// axis) instead of running one.
        #[arg(long)]
        uniform: Option<PathBuf>,
    },
    /// Lists GPU adapters: type, backend, limits, f64 support; with
    /// --shader DIR, the shader's variants and what each lane carries.
    Info {
        /// Write the WGSL of every integrator pipeline variant (precision,
        /// adapter kind, parts) into DIR and print each one's footprint:
        /// bytes of private arrays indexed at run time (after `spirv-opt`,
        /// from Debian's spirv-tools) and of function variables, its
        /// instructions, and the emulated f64 divisions and roots per slip
        /// trial on a probe of random instances (on any adapter, the
        /// software one included), and, where Mesa 25's RADV is unpacked
        /// (`.ci/radv.sh`), ACO's registers and spills of every hardware
        /// pipeline on navi31 and navi21, instead of listing adapters.
        #[arg(long, value_name = "DIR")]
        shader: Option<PathBuf>,
        /// Print only the registers of every hardware batch pipeline: every
        /// statistic the system's Vulkan device lists (NVIDIA's register
        /// count), and ACO's on RADV's null navi31 and navi21 where Mesa
        /// 25's RADV is unpacked (`.ci/radv.sh`), against issue 57's
        /// budgets.
        #[arg(long, conflicts_with = "shader")]
        registers: bool,
    },
    /// The RADV probe's child (`pidm info --shader`): compiles the
    /// pipelines JOBS lists on the Vulkan device its environment picks and
    /// prints the driver's statistics as JSON.
    #[command(hide = true, name = "isa-probe")]
    IsaProbe { jobs: PathBuf },
    /// Validates a scene and prints its grid, instance count and cost
    /// estimate without running it.
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Print one JSON object instead: name, layout, axes, instances,
        /// shape, baselines, output bytes and the cost estimate.
        #[arg(long)]
        json: bool,
    },
    /// Reruns points scenes (the paper's experiments) and writes a Markdown
    /// report: converged steps beside the paper's, invariants checked.
    Report {
        /// Points scenes [default: sweeps/paper.toml sweeps/paper_text.toml,
        /// built into pidm, so any directory works].
        scenes: Vec<PathBuf>,
        /// Output Markdown file.
        #[arg(long, default_value = "results/paper.md")]
        out: PathBuf,
    },
    /// Work-precision study: error of the step maps against wall time for
    /// each method and setting; writes a table, HDF5 data, a plot and
    /// results/accuracy.md.
    Accuracy {
        /// Scenes to study [default: sweeps/paper.toml, built into pidm, so
        /// any directory works].
        scenes: Vec<PathBuf>,
        /// Where the data, plots and summary go.
        #[arg(long, default_value = "results")]
        out_dir: PathBuf,
        /// Step sizes of the fixed-step Karnopp baseline [s].
        #[arg(long, value_delimiter = ',', default_value = "1e-5,3e-6,1e-6,3e-7",
              value_parser = positive_finite)]
        karnopp_steps: Vec<f64>,
        /// Also study the GPU path, on any adapter, in every precision it
        /// offers.
        #[arg(long)]
        gpu: bool,
    },
    /// Draws PNG pictures of a result file: heatmaps of the step maps (and
    /// coupling maps against the 1-DOF baselines), line or bar charts for
    /// 1-D and points scenes, and the stored trajectories.
    Plot {
        /// The result file (HDF5) written by `pidm run`.
        file: PathBuf,
        /// Output folder [default: results/plots/<file stem>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// The grid axis across the maps, by key (`axis.x.voltage`)
        /// [default: of the two axes with the most values, the earlier].
        #[arg(long, value_name = "KEY")]
        x: Option<String>,
        /// The grid axis up the maps, by key [default: of the two axes with
        /// the most values, the later].
        #[arg(long, value_name = "KEY")]
        y: Option<String>,
        /// Hold a grid axis at one of its values (repeatable): only the
        /// maps at that value are drawn [default: one map per combination
        /// of the other axes' values].
        #[arg(long, value_name = "KEY=VALUE", value_parser = key_value)]
        at: Vec<(String, f64)>,
    },
    /// Writes a points scene of seeded random instances to stdout, measured
    /// over a fixed window (`measure = "window"`).
    RandomScene {
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 16)]
        count: usize,
        /// Scene periods of the window.
        #[arg(long, default_value_t = 4)]
        cycles: u32,
        /// Leading periods discarded.
        #[arg(long, default_value_t = 1)]
        settle: u32,
        /// Write the scene as a `[random]` table (seed and count, a few
        /// lines) instead of one `[[points]]` entry per instance (about 680
        /// bytes each): the same instances, bit for bit.
        #[arg(long)]
        compact: bool,
    },
    /// Measures simulated seconds per wall second per core on a scene.
    Bench {
        /// The scene file [default: sweeps/paper.toml, built into pidm, so
        /// any directory works].
        scene: Option<PathBuf>,
        /// Keep measuring for at least this many seconds per thread setting.
        #[arg(long, default_value_t = 2.0, value_parser = positive_finite)]
        seconds: f64,
    },
}

/// A `KEY=VALUE` flag value with a finite number.
fn key_value(text: &str) -> Result<(String, f64), String> {
    let Some((key, value)) = text.split_once('=') else {
        return Err(format!(
            "{text:?}: expected KEY=VALUE, e.g. axis.y.frequency=20"
        ));
    };
    match value.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok((key.trim().to_owned(), v)),
        _ => Err(format!("{text:?}: {value:?} is not a finite number")),
    }
}

impl Command {
    /// Whether the command may look for GPU adapters.
    fn looks_for_gpu(&self) -> bool {
        match self {
            Command::Run { backend, .. } | Command::RefineStudy { backend, .. } => {
                *backend != backend::BackendChoice::Cpu
            }
            Command::Fit(fit) => fit.backend != backend::BackendChoice::Cpu,
            Command::Sensitivity(s) => s.args.backend != backend::BackendChoice::Cpu,
            Command::Optimize(o) => o.args.backend != backend::BackendChoice::Cpu,
            Command::Info { .. } | Command::Bench { .. } => true,
            Command::Accuracy { gpu, .. } => *gpu,
            _ => false,
        }
    }
}

/// A flag value that must be a finite number above zero.
fn positive_finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() && value > 0.0 => Ok(value),
        Ok(value) => Err(format!("{value} is not a finite number above 0")),
        Err(e) => Err(format!("{text:?} is not a number ({e})")),
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Run {
            scene,
            out,
            threads,
            backend,
            precision,
            shard,
            resume,
            chunk_size,
            verify,
            progress,
            profile,
        } => {
            if profile {
                pidm::profile::enable();
            }
            if chunk_size == Some(0) {
                anyhow::bail!("--chunk-size must be at least 1");
            }
            let failed = commands::run(&commands::RunOptions {
                scene,
                out,
                threads,
                backend,
                precision,
                table_limit: 64,
                scope: pidm::run::RunScope {
                    shard,
                    resume,
                    chunk_size,
                    verify,
                    progress,
                },
            })?;
            if failed > 0 {
                let (noun, their) = if failed == 1 {
                    ("instance", "its")
                } else {
                    ("instances", "their")
                };
                eprintln!(
                    "pidm: {failed} {noun} did not finish normally; {their} map entries are 0 \
                     and /maps/status says why"
                );
                return Ok(ExitCode::from(3));
            }
        }
        Command::Fit(fit) => {
            if commands::fit(&fit)? {
                eprintln!("pidm: stopped by SIGINT: the best point so far is written");
                return Ok(ExitCode::from(130));
            }
        }
        Command::Sensitivity(s) => commands::sensitivity(&s)?,
        Command::Optimize(o) => commands::optimize(&o)?,
        Command::Merge { out, shards } => commands::merge(&out, &shards)?,
        Command::Check { scene, json } => commands::check(&scene, json)?,
        Command::Plot {
            file,
            out,
            x,
            y,
            at,
        } => pidm::plot::run(&file, out.as_deref(), &pidm::plot::View { x, y, at })?,
        Command::RefineStudy {
            scene,
            out_dir,
            backend,
            uniform,
        } => commands::refine_study(&scene, &out_dir, backend, uniform.as_deref())?,
        Command::Info {
            registers: true, ..
        } => commands::registers()?,
        Command::Info { shader: None, .. } => commands::info()?,
        Command::Info {
            shader: Some(dir), ..
        } => commands::shader_info(&dir)?,
        Command::IsaProbe { jobs } => pidm::gpu::isa::probe::run(&jobs)?,
        Command::Report { scenes, out } => commands::report(&scenes, &out)?,
        Command::Accuracy {
            scenes,
            out_dir,
            karnopp_steps,
            gpu,
        } => commands::accuracy(&scenes, &out_dir, &karnopp_steps, gpu)?,
        Command::RandomScene {
            seed,
            count,
            cycles,
            settle,
            compact,
        } => print!(
            "{}",
            if compact {
                commands::random_scene_compact(seed, count, cycles, settle)?
            } else {
                commands::random_scene(seed, count, cycles, settle)?
            }
        ),
        Command::Bench { scene, seconds } => commands::bench(scene.as_deref(), seconds)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// This process's command line with `--resume` added (once), quoted for a
/// POSIX shell.
fn resume_command() -> String {
    let mut args: Vec<String> = std::env::args_os()
        .map(|a| shell_quote(&a.to_string_lossy()))
        .collect();
    if !args.iter().any(|a| a == "--resume") {
        args.push("--resume".into());
    }
    args.join(" ")
}

/// `text` as one word of a POSIX shell command.
fn shell_quote(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "_-./=:,+@%".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', "'\\''"))
    }
}

fn main() -> ExitCode {
    // Output piped into a reader that stops early (`pidm check | head`)
    // ends the process quietly, as it does every Unix tool, instead of a
    // panic in `println!`.
    // SAFETY: called first in `main`, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    pidm::profile::start();
    let cli = Cli::parse();
    // Mesa's GL driver complains of an unset or invalid XDG_RUNTIME_DIR on
    // stderr when wgpu looks for adapters (machines without a desktop
    // session): give it a private folder of this process's instead,
    // removed at the end.
    let runtime = cli
        .command
        .looks_for_gpu()
        .then(pidm::gpu::private_runtime_dir)
        .flatten();
    if let Some(dir) = &runtime {
        // SAFETY: still before any thread exists (parsing the command line
        // starts none).
        unsafe {
            std::env::set_var("XDG_RUNTIME_DIR", dir);
        }
    }
    let code = exit_code(cli);
    if let Some(dir) = runtime {
        let _ = std::fs::remove_dir(dir);
    }
    code
}

/// Runs the command and turns its outcome into the exit status, printing
/// the error chain.
fn exit_code(cli: Cli) -> ExitCode {
    let resumable = matches!(cli.command, Command::Run { .. });
    match run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("pidm: error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            // A run stopped by SIGINT or SIGTERM exits with 128 + the
            // signal, as a shell reports a process the signal ended.
            if let Some(signal) = pidm::run::stop_signal() {
                let name = if signal == libc::SIGTERM {
                    "SIGTERM"
                } else {
                    "SIGINT"
                };
                if resumable {
                    eprintln!(
                        "pidm: stopped by {name}; continue the run with:\n  {}",
                        resume_command()
                    );
                } else {
                    eprintln!("pidm: stopped by {name}; nothing was written");
                }
                return ExitCode::from(128 + signal.clamp(0, 127) as u8);
            }
            ExitCode::FAILURE
        }
    }
}
