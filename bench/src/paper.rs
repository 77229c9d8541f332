//! `paper`: the paper's experiments on our generated shelf datasets.
//!
//! For each dataset (`shelf_zero`, `shelf_height`, `shelf_height_rot`) SPARK and FLAME learn
//! incrementally from the training set's solved paths; at each training size N (10, 30, 50, 100,
//! 300, 500) every method plans the same test problems, and SPARK retrieval is timed with the
//! metric tree and the linear scan on the test scenes. Uniform sampling does not depend on N, but
//! it is planned again at every N, right beside the learned methods, so that every ratio compares
//! runs made under the same machine load (machines here are shared).
//!
//! Problem sets are read from `--problems DIR` (`DIR/<dataset>` and `DIR/<dataset>_test`, and
//! for the transfer case `DIR/<dataset>_place[_test]`, as `ember problems [--place]` writes them);
//! a missing or too small set is generated there first (the generator is deterministic, so a
//! larger set extends a smaller one).
//!
//! Writes tables to the terminal, `paper.csv` and `retrieval.csv`, and plots like the paper's
//! figures (`time_<dataset>.svg/png`: mean planning time against N; `retrieval.svg/png`:
//! retrieval time against database size) under `--out DIR`. Ends with one line per (dataset,
//! method, N): `RESULT paper dataset=<d> method=<uniform|spark|flame> n_train=<N>
//! n_test=<n> solved=<k> mean_ms=<f> median_ms=<f> retrieval_us=<f>`, and one per (dataset, N):
//! `RESULT paper_retrieval dataset=<d> n_train=<N> spark_entries=<e> tree_us=<f> linear_us=<f>
//! flame_entries=<e> flame_us=<f>`, and one per dataset for the oracle diagnostic (each test
//! problem's own stored solution as the only local sampler, planned beside uniform: the ceiling
//! of the paper's sampler): `RESULT paper_oracle dataset=<d> n_test=<n> solved=<k>
//! mean_ms=<f> median_ms=<f> uniform_mean_ms=<f> gain=<f>`.
//!
//! `--quick`: N ∈ {10, 50, 100}, 25 test problems, 5 s limit — a few minutes in all.

use crate::learning::{plan_sets, prepare, train_one, EvalOptions, Method, Outcome, Run, TestCase};
use crate::plot::{self, Chart, Series};
use ember_engine::experience::flame::octoboxes;
use ember_engine::experience::spark::spark_pairs;
use ember_engine::experience::{Database, Experience, ExperienceParams, FlameDb, SparkDb};
use ember_engine::planning::PlannerParams;
use ember_engine::problems::{self, GenerateOptions, Problem, ProblemSet, Task};
use ember_engine::robot::Robot;
use ember_engine::world::map::MapParams;
use ember_sdk::stats::summary;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The robot (default the built-in Fetch); problem sets are generated for it.
    #[command(flatten)]
    robot: ember_engine::robot::RobotArgs,
    /// Folder of the problem sets (generated there when missing).
    #[arg(long, default_value = "ember-data/problems")]
    problems: PathBuf,
    /// Datasets, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "shelf_zero,shelf_height,shelf_height_rot"
    )]
    datasets: Vec<String>,
    /// Training sizes N, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "10,30,50,100,300,500")]
    sizes: Vec<usize>,
    /// Test problems per dataset.
    #[arg(long, default_value_t = 100)]
    n_test: usize,
    /// Time limit per plan, seconds (a failure counts as the limit).
    #[arg(long, default_value_t = 10.0)]
    time_limit: f64,
    /// Planner seed (each problem uses seed + index).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// RRT-Connect range (default: the planner's).
    #[arg(long)]
    range: Option<f64>,
    /// Where tables and plots go.
    #[arg(long, default_value = "ember-data/paper")]
    out: PathBuf,
    /// Reduced run: N ∈ {10, 50, 100}, 25 test problems, 5 s limit.
    #[arg(long)]
    quick: bool,
    /// Datasets that also run the transfer case (pick-trained experience on place problems).
    #[arg(long, value_delimiter = ',', default_value = "shelf_height_rot")]
    transfer: Vec<String>,
    /// Skip the transfer case.
    #[arg(long)]
    no_transfer: bool,
    /// Also test path states every STEP (configuration distance) for criticality.
    #[arg(long)]
    interpolate: Option<f64>,
    /// Override σ (default 0.2, the paper's).
    #[arg(long)]
    sigma: Option<f64>,
    /// Override λ (default 0.5, the paper's).
    #[arg(long)]
    lambda: Option<f64>,
    /// Override SPARK's retrieval radius `d_radius` (default 0.2, the authors' effective one).
    #[arg(long)]
    d_radius: Option<f64>,
    /// Override FLAME's match radius in metres (default 0.2, the authors').
    #[arg(long)]
    flame_radius: Option<f64>,
}

/// What the methods did at one training size N: (method name as in `RESULT` lines, outcome).
/// Uniform sampling is planned at every N too, interleaved with the learned methods problem by
/// problem ([`plan_sets`]), so that each ratio compares runs made under the same machine load.
struct Row {
    n: usize,
    outcomes: Vec<(&'static str, Outcome)>,
}

impl Row {
    /// Plans `cases` with each named run, interleaved.
    fn planned(
        n: usize,
        cases: &[TestCase],
        runs: &[(&'static str, Run)],
        options: &EvalOptions,
    ) -> Row {
        let plans: Vec<Run> = runs.iter().map(|&(_, run)| run).collect();
        let outcomes = plan_sets(cases, &plans, options);
        Row {
            n,
            outcomes: runs.iter().map(|&(name, _)| name).zip(outcomes).collect(),
        }
    }

    fn get(&self, method: &str) -> &Outcome {
        &self
            .outcomes
            .iter()
            .find(|(m, _)| *m == method)
            .expect("measured")
            .1
    }

    /// `method mean_ms, ...` for progress lines.
    fn means(&self) -> String {
        let parts: Vec<String> = self
            .outcomes
            .iter()
            .map(|(m, o)| format!("{m} {:.2}", o.mean_ms))
            .collect();
        format!("{} ms", parts.join(", "))
    }
}

/// SPARK and FLAME databases learned incrementally from the first problems of a set.
struct Learner {
    experience: Experience,
    /// Problems of the set learned so far.
    trained: usize,
}

impl Learner {
    fn new(params: &ExperienceParams) -> Self {
        Learner {
            experience: Experience::new(params.clone(), MapParams::default().resolution),
            trained: 0,
        }
    }

    /// Learns the set's problems up to the first `n`.
    fn train_to(
        &mut self,
        robot: &Robot,
        problems: &[Problem],
        n: usize,
        interpolate: Option<f64>,
    ) -> anyhow::Result<()> {
        let n = n.min(problems.len());
        for p in &problems[self.trained.min(n)..n] {
            train_one(robot, p, interpolate, &mut self.experience)?;
        }
        self.trained = self.trained.max(n);
        Ok(())
    }
}

/// Column captions of the pick table and the transfer table (same order as the rows).
const PICK_COLUMNS: [(&str, &str); 3] = [
    ("uniform", "uniform"),
    ("spark", "SPARK"),
    ("flame", "FLAME"),
];
const TRANSFER_COLUMNS: [(&str, &str); 5] = [
    ("uniform", "uniform"),
    ("spark", "SPARK"),
    ("flame", "FLAME"),
    ("spark_tx", "SPARK (TX)"),
    ("flame_tx", "FLAME (TX)"),
];

/// Retrieval timings at one training size.
struct RetrievalRow {
    n_train: usize,
    spark_entries: usize,
    tree_us: f64,
    linear_us: f64,
    flame_entries: usize,
    flame_us: f64,
}

/// Everything measured on one dataset.
struct DatasetRun {
    name: String,
    /// Pick problems per N: uniform, SPARK, FLAME.
    rows: Vec<Row>,
    retrieval: Vec<RetrievalRow>,
    /// The transfer case (place problems, the can held) per N: uniform, SPARK and FLAME learned
    /// on place problems, SPARK and FLAME learned on pick problems (TX).
    transfer: Vec<Row>,
    /// Uniform and the oracle (each test problem's own solution as the sampler), planned side
    /// by side: the most any experience could gain with the paper's sampler.
    oracle: Row,
}

/// A generator progress callback redrawing `label: done/count` when `done` changes.
fn progress_line(label: String, count: usize) -> impl FnMut(usize, usize) {
    let mut shown = usize::MAX;
    move |done, _| {
        if done != shown {
            shown = done;
            eprint!("\r{label}: {done}/{count}");
        }
    }
}

/// Loads the `task` set of `dataset` (its test set when `test`) from `root`, generating it
/// first when it holds fewer than `count` problems.
pub(crate) fn problem_set(
    robot: &Robot,
    root: &Path,
    dataset: &str,
    task: Task,
    test: bool,
    count: usize,
) -> anyhow::Result<ProblemSet> {
    let name = task.set_name(dataset, test);
    let dir = root.join(&name);
    let have = ProblemSet::load(&dir, robot)
        .map(|s| s.problems.len())
        .unwrap_or(0);
    if have < count {
        let spec = problems::dataset(dataset)
            .ok_or_else(|| problems::ProblemError::UnknownDataset(dataset.to_string()))?;
        let t = Instant::now();
        let options = GenerateOptions {
            count,
            seed: task.set_seed(1, test),
            task,
            ..Default::default()
        };
        let mut progress = progress_line(format!("generating {name}"), count);
        let report = problems::generate(robot, &spec, &options, &dir, &mut progress)?;
        eprintln!(
            " ({:.0} s; {} candidates, {} without IK solution, {} unsolved)",
            t.elapsed().as_secs_f64(),
            report.attempts,
            report.no_ik,
            report.unsolved
        );
        anyhow::ensure!(
            report.written == count,
            "only {} of {count} problems of {name} found",
            report.written
        );
    }
    let mut set = ProblemSet::load(&dir, robot)?;
    set.problems.truncate(count);
    Ok(set)
}

/// SPARK retrieval with the tree and the linear scan, FLAME lookups: medians over the cases.
fn time_retrieval(
    n_train: usize,
    cases: &[TestCase],
    spark: &SparkDb,
    flame: &FlameDb,
    params: &ExperienceParams,
) -> anyhow::Result<RetrievalRow> {
    let (mut tree, mut linear, mut flame_t) = (Vec::new(), Vec::new(), Vec::new());
    for case in cases {
        let pairs = spark_pairs(&case.problem.scene, params);
        let t = Instant::now();
        let r = spark.retrieve(&pairs);
        tree.push(t.elapsed().as_secs_f64() * 1e6);
        let t = Instant::now();
        let l = spark.retrieve_linear(&pairs);
        linear.push(t.elapsed().as_secs_f64() * 1e6);
        anyhow::ensure!(
            r.entries == l.entries && r.samplers.len() == l.samplers.len(),
            "metric tree and linear scan disagree on problem {}",
            case.problem.index
        );
        let boxes = octoboxes(&case.map);
        let t = Instant::now();
        std::hint::black_box(flame.retrieve(&boxes));
        flame_t.push(t.elapsed().as_secs_f64() * 1e6);
    }
    Ok(RetrievalRow {
        n_train,
        spark_entries: spark.len(),
        tree_us: summary(&mut tree).0,
        linear_us: summary(&mut linear).0,
        flame_entries: flame.len(),
        flame_us: summary(&mut flame_t).0,
    })
}

fn run_dataset(
    robot: &Robot,
    args: &Args,
    dataset: &str,
    sizes: &[usize],
    n_test: usize,
    options: &EvalOptions,
) -> anyhow::Result<DatasetRun> {
    let max_n = sizes.iter().copied().max().unwrap_or(0);
    let set = |task, test, count| problem_set(robot, &args.problems, dataset, task, test, count);
    let train = set(Task::Pick, false, max_n)?;
    let test = set(Task::Pick, true, n_test)?;
    let transfer_here = !args.no_transfer && args.transfer.iter().any(|d| d == dataset);
    let (place_train, place_test) = if transfer_here {
        (
            set(Task::Place, false, max_n)?.problems,
            set(Task::Place, true, n_test)?.problems,
        )
    } else {
        Default::default()
    };
    let place_cases = prepare(robot, &place_test)?;
    let t = Instant::now();
    let cases = prepare(robot, &test.problems)?;
    eprintln!(
        "{dataset}: {} training, {} test problems ({} test maps rendered in {:.1} s)",
        train.problems.len(),
        cases.len(),
        cases.len(),
        t.elapsed().as_secs_f64()
    );
    let defaults = ExperienceParams::default();
    let params = ExperienceParams {
        sigma: args.sigma.unwrap_or(defaults.sigma),
        lambda: args.lambda.unwrap_or(defaults.lambda),
        d_radius: args.d_radius.unwrap_or(defaults.d_radius),
        flame_radius: args.flame_radius.unwrap_or(defaults.flame_radius),
        ..defaults
    };
    let (mut pick, mut place) = (Learner::new(&params), Learner::new(&params));
    let (mut rows, mut retrieval, mut transfer) = (Vec::new(), Vec::new(), Vec::new());
    for &n in sizes {
        let t = Instant::now();
        pick.train_to(robot, &train.problems, n, args.interpolate)?;
        let train_s = t.elapsed().as_secs_f64();
        let exp = &pick.experience;
        let (spark, flame) = (&exp.spark, &exp.flame);
        let runs = [
            ("uniform", (Method::Uniform, exp)),
            ("spark", (Method::Spark, exp)),
            ("flame", (Method::Flame, exp)),
        ];
        let row = Row::planned(n, &cases, &runs, options);
        eprintln!(
            "  N={n:<4} (+{train_s:.1} s training; SPARK {} entries, FLAME {}): {}",
            spark.len(),
            flame.len(),
            row.means()
        );
        rows.push(row);
        retrieval.push(time_retrieval(n, &cases, spark, flame, &params)?);
        if !transfer_here {
            continue;
        }
        place.train_to(robot, &place_train, n, args.interpolate)?;
        let runs = [
            ("uniform", (Method::Uniform, exp)),
            ("spark", (Method::Spark, &place.experience)),
            ("flame", (Method::Flame, &place.experience)),
            ("spark_tx", (Method::Spark, exp)),
            ("flame_tx", (Method::Flame, exp)),
        ];
        let row = Row::planned(n, &place_cases, &runs, options);
        eprintln!("  place N={n:<4}: {}", row.means());
        transfer.push(row);
    }
    let exp = &pick.experience;
    let runs = [
        ("uniform", (Method::Uniform, exp)),
        ("oracle", (Method::Oracle, exp)),
    ];
    let oracle = Row::planned(0, &cases, &runs, options);
    eprintln!("  oracle: {}", oracle.means());
    Ok(DatasetRun {
        name: dataset.to_string(),
        rows,
        retrieval,
        transfer,
        oracle,
    })
}

/// Prints one table row per N: solved, mean and median per method, and each learned method's
/// gain (uniform mean / its mean).
fn print_rows(title: &str, rows: &[Row], columns: &[(&str, &str)]) {
    let Some(first) = rows.first() else { return };
    println!("\n{title} ({} test problems; planning time includes retrieval; a failure counts as the limit)", first.outcomes[0].1.n);
    let mut head = format!("{:>5}", "N");
    for (_, caption) in columns {
        head += &format!(" | {:>21}", format!("{caption} solved/mean/med"));
    }
    println!("{head} | gain");
    for row in rows {
        let mut line = format!("{:>5}", row.n);
        for (m, _) in columns {
            let o = row.get(m);
            line += &format!(" | {:>5} {:>7.2} {:>7.2}", o.solved, o.mean_ms, o.median_ms);
        }
        let uniform = row.get("uniform").mean_ms;
        let gains: Vec<String> = columns[1..]
            .iter()
            .map(|(m, _)| format!("{:.2}x", uniform / row.get(m).mean_ms))
            .collect();
        println!("{line} | {}", gains.join(" "));
    }
}

fn print_tables(run: &DatasetRun) {
    print_rows(&run.name, &run.rows, &PICK_COLUMNS);
    let (uniform, oracle) = (run.oracle.get("uniform"), run.oracle.get("oracle"));
    println!(
        "oracle (own solution as the sampler): solved {} mean {:.2} median {:.2} ms against uniform {} {:.2} {:.2}: {:.2}x",
        oracle.solved,
        oracle.mean_ms,
        oracle.median_ms,
        uniform.solved,
        uniform.mean_ms,
        uniform.median_ms,
        uniform.mean_ms / oracle.mean_ms
    );
    println!(
        "{:>5} | {:>9} {:>9} {:>9} | {:>9} {:>9} | {:>9} {:>9}",
        "N", "entries", "tree_us", "linear_us", "retr_S", "samplers", "FLAME", "flame_us"
    );
    for (r, row) in run.retrieval.iter().zip(&run.rows) {
        let s = row.get("spark");
        println!(
            "{:>5} | {:>9} {:>9.1} {:>9.1} | {:>9.0} {:>9.0} | {:>9} {:>9.1}",
            r.n_train,
            r.spark_entries,
            r.tree_us,
            r.linear_us,
            s.entries,
            s.samplers,
            r.flame_entries,
            r.flame_us
        );
    }
}

/// Appends `rows` to a CSV text and writes their mean-time chart to `<stem>.svg/png`.
fn write_rows(
    out: &Path,
    stem: &str,
    title: &str,
    dataset: &str,
    rows: &[Row],
    columns: &[(&str, &str)],
    csv: &mut String,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut series = Vec::new();
    for (m, caption) in columns {
        series.push(Series {
            name: caption.to_string(),
            points: rows
                .iter()
                .map(|r| (r.n as f64, r.get(m).mean_ms))
                .collect(),
        });
        for r in rows {
            writeln!(csv, "{dataset},{m},{},{}", r.n, r.get(m).csv())?;
        }
    }
    let chart = Chart {
        title,
        x_label: "training problems N",
        y_label: "mean time (ms)",
        log_x: true,
        log_y: false,
        series,
    };
    plot::write(&out.join(stem), &chart)
}

fn write_outputs(out: &Path, runs: &[DatasetRun]) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out)?;
    let header = format!("dataset,method,n_train,{}\n", Outcome::CSV_HEADER);
    let (mut csv, mut tcsv) = (header.clone(), header);
    let mut rcsv =
        String::from("dataset,n_train,spark_entries,tree_us,linear_us,flame_entries,flame_us\n");
    let mut files = Vec::new();
    let mut retrieval_series = Vec::new();
    for run in runs {
        let name = &run.name;
        files.extend(write_rows(
            out,
            &format!("time_{name}"),
            &format!("{name}: mean planning time (incl. retrieval)"),
            name,
            &run.rows,
            &PICK_COLUMNS,
            &mut csv,
        )?);
        if !run.transfer.is_empty() {
            files.extend(write_rows(
                out,
                &format!("transfer_{name}"),
                &format!("{name}, place with the object held: mean planning time"),
                name,
                &run.transfer,
                &TRANSFER_COLUMNS,
                &mut tcsv,
            )?);
        }
        for r in &run.retrieval {
            writeln!(
                rcsv,
                "{name},{},{},{:.1},{:.1},{},{:.1}",
                r.n_train, r.spark_entries, r.tree_us, r.linear_us, r.flame_entries, r.flame_us
            )?;
        }
        let pts = |f: &dyn Fn(&RetrievalRow) -> f64| {
            run.retrieval
                .iter()
                .map(|r| (r.spark_entries as f64, f(r)))
                .collect()
        };
        retrieval_series.push(Series {
            name: format!("{name} tree"),
            points: pts(&|r| r.tree_us),
        });
        retrieval_series.push(Series {
            name: format!("{name} linear"),
            points: pts(&|r| r.linear_us),
        });
    }
    let chart = Chart {
        title: "SPARK retrieval time per query scene",
        x_label: "database entries",
        y_label: "median retrieval time (µs)",
        log_x: true,
        log_y: true,
        series: retrieval_series,
    };
    files.extend(plot::write(&out.join("retrieval"), &chart)?);
    for (name, text) in [
        ("paper.csv", csv),
        ("retrieval.csv", rcsv),
        ("transfer.csv", tcsv),
    ] {
        std::fs::write(out.join(name), text)?;
        files.push(out.join(name));
    }
    Ok(files)
}

/// Prints the `RESULT <kind>` line of every (method, N) of `rows`.
fn print_results(kind: &str, dataset: &str, rows: &[Row]) {
    for r in rows {
        for (m, o) in &r.outcomes {
            println!(
                "RESULT {kind} dataset={dataset} method={m} n_train={} n_test={} {}",
                r.n,
                o.n,
                o.result_keys()
            );
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = args.robot.spec("fetch").load()?;
    let (mut sizes, n_test, time_limit) = if args.quick {
        (vec![10, 50, 100], 25, 5.0)
    } else {
        (args.sizes.clone(), args.n_test, args.time_limit)
    };
    sizes.sort_unstable();
    sizes.dedup();
    anyhow::ensure!(
        !sizes.is_empty() && sizes[0] > 0,
        "--sizes needs positive sizes"
    );
    let options = EvalOptions {
        time_limit,
        seed: args.seed,
        range: args.range.unwrap_or(PlannerParams::default().range),
    };
    let t = Instant::now();
    let mut runs = Vec::new();
    for dataset in &args.datasets {
        let run = run_dataset(&robot, &args, dataset, &sizes, n_test, &options)?;
        print_tables(&run);
        print_rows(
            &format!(
                "{}, transfer: place problems with the can held; TX = learned on pick problems",
                run.name
            ),
            &run.transfer,
            &TRANSFER_COLUMNS,
        );
        runs.push(run);
    }
    let files = write_outputs(&args.out, &runs)?;
    println!("\nwritten ({:.0} s in all):", t.elapsed().as_secs_f64());
    for f in files {
        println!("  {}", f.display());
    }
    for run in &runs {
        print_results("paper", &run.name, &run.rows);
    }
    for run in &runs {
        print_results("paper_transfer", &run.name, &run.transfer);
    }
    for run in &runs {
        let (uniform, oracle) = (run.oracle.get("uniform"), run.oracle.get("oracle"));
        println!(
            "RESULT paper_oracle dataset={} n_test={} solved={} mean_ms={:.3} median_ms={:.3} uniform_mean_ms={:.3} gain={:.2}",
            run.name,
            oracle.n,
            oracle.solved,
            oracle.mean_ms,
            oracle.median_ms,
            uniform.mean_ms,
            uniform.mean_ms / oracle.mean_ms
        );
    }
    for run in &runs {
        for r in &run.retrieval {
            println!(
                "RESULT paper_retrieval dataset={} n_train={} spark_entries={} tree_us={:.1} linear_us={:.1} flame_entries={} flame_us={:.1}",
                run.name, r.n_train, r.spark_entries, r.tree_us, r.linear_us, r.flame_entries, r.flame_us
            );
        }
    }
    Ok(())
}
