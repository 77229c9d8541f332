//! `validity --problems DIR...`: Ember's start/goal verdicts against an exact mesh checker on
//! FCL (what MoveIt uses), on the same problems.
//!
//! Ember decides start and goal on its exact geometry (the robot named by `--robot`,
//! `--srdf`, ...). The truth comes from `--truth CSV` (columns `set,index,start_free,goal_free`,
//! as `fcl_validity.py` writes), or is computed by running the FCL tool (`--fcl-tool`, default
//! `../shared/tools/fcl_validity.py`) on the official description (`--truth-urdf`,
//! `--truth-srdf`, `--truth-mesh-dir`) in a virtualenv under `target/` with `python-fcl`. A
//! problem agrees when both its start and its goal verdicts agree. Also counted: what the
//! sphere model alone would refuse. Ends with `RESULT validity set=<folder> n= agree=
//! agreement= ours_refused= truth_refused= spheres_refused=` per folder and `set=all`.

use ember_engine::collision::exact::ExactChecker;
use ember_engine::collision::SphereChecker;
use ember_engine::planning::Goal;
use ember_engine::problems::ProblemSet;
use ember_engine::robot::RobotArgs;
use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Command;

#[derive(clap::Args)]
pub struct Args {
    /// Problem folders (sceneNNNN.yaml + requestNNNN.yaml each).
    #[arg(long, num_args = 1.., required = true)]
    problems: Vec<PathBuf>,
    /// The robot Ember checks with.
    #[command(flatten)]
    robot: RobotArgs,
    /// Ground truth CSV (set,index,start_free,goal_free,...); computed with FCL when absent.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// The FCL checker to run when no --truth is given.
    #[arg(long, default_value = "../shared/tools/fcl_validity.py")]
    fcl_tool: PathBuf,
    /// URDF of the official description the FCL checker uses.
    #[arg(
        long,
        default_value = "../shared/reference/robots/fetch/vamp/fetch.urdf"
    )]
    truth_urdf: PathBuf,
    /// SRDF of the official description.
    #[arg(
        long,
        default_value = "../shared/reference/robots/fetch/vamp/fetch.srdf"
    )]
    truth_srdf: PathBuf,
    /// Mesh folder of the official description.
    #[arg(long, default_value = "../shared/reference/robots/fetch/vamp/meshes")]
    truth_mesh_dir: PathBuf,
    /// List every disagreement.
    #[arg(long)]
    verbose: bool,
}

type Truth = HashMap<(String, usize), (bool, bool, String, String)>;

fn read_truth(path: &PathBuf) -> anyhow::Result<Truth> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| anyhow::anyhow!("{}: no column '{name}'", path.display()))
    };
    let (cs, ci, cst, cg) = (
        col("set")?,
        col("index")?,
        col("start_free")?,
        col("goal_free")?,
    );
    let (csc, cgc) = (col("start_contact").ok(), col("goal_contact").ok());
    let mut out = Truth::new();
    for (n, l) in lines.enumerate() {
        let f: Vec<&str> = l.split(',').collect();
        let get = |i: usize| {
            f.get(i)
                .copied()
                .ok_or_else(|| anyhow::anyhow!("{}: line {} is short", path.display(), n + 2))
        };
        let contact = |c: Option<usize>| c.and_then(|i| f.get(i)).unwrap_or(&"").to_string();
        out.insert(
            (get(cs)?.to_string(), get(ci)?.parse()?),
            (
                get(cst)? == "1",
                get(cg)? == "1",
                contact(csc),
                contact(cgc),
            ),
        );
    }
    Ok(out)
}

fn run_fcl(args: &Args) -> anyhow::Result<PathBuf> {
    let python = crate::python::venv(
        "fcl-venv",
        &["python-fcl", "numpy", "pyyaml", "trimesh"],
        "import fcl, numpy, yaml, trimesh",
    )?;
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/fcl_truth.csv");
    let ok = Command::new(python)
        .arg(&args.fcl_tool)
        .arg("--urdf")
        .arg(&args.truth_urdf)
        .arg("--srdf")
        .arg(&args.truth_srdf)
        .arg("--mesh-dir")
        .arg(&args.truth_mesh_dir)
        .arg("--out")
        .arg(&out)
        .args(&args.problems)
        .stdout(std::process::Stdio::null())
        .status()?
        .success();
    anyhow::ensure!(ok, "{} failed", args.fcl_tool.display());
    Ok(out)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let truth_file = match &args.truth {
        Some(t) => t.clone(),
        None => run_fcl(&args)?,
    };
    let truth = read_truth(&truth_file)?;
    let robot = args.robot.spec("fetch").load()?;
    println!(
        "Ember: {} ({} spheres), truth: {}",
        args.robot.robot.as_deref().unwrap_or("fetch"),
        robot.spheres().len(),
        truth_file.display()
    );
    println!(
        "{:<24} {:>4} {:>6} {:>10} {:>13} {:>14} {:>16}",
        "set", "n", "agree", "agreement", "ours_refused", "truth_refused", "spheres_refused"
    );
    let mut lines = Vec::new();
    let mut total = [0usize; 5];
    for dir in &args.problems {
        let set = ProblemSet::load(dir, &robot)?;
        let mut counts = [0usize; 5]; // n, agree, ours refused, truth refused, spheres refused
        for p in &set.problems {
            let Some(&(t_start, t_goal, ref t_sc, ref t_gc)) =
                truth.get(&(set.name.clone(), p.index))
            else {
                anyhow::bail!("{}: problem {} is not in the truth file", set.name, p.index);
            };
            let Goal::Joints(goals) = &p.request.goal else {
                anyhow::bail!("{}: problem {} has no joint goal", set.name, p.index);
            };
            let r = p.scene.robot_with(&robot, &p.request.start_joints)?;
            let env = p.scene.environment()?;
            let mut exact = ExactChecker::new(&r, &env);
            let mut spheres = SphereChecker::new(&r, &env);
            let goal = &goals[0];
            let (sc, gc) = (exact.contact(&p.request.start), exact.contact(goal));
            let (s_free, g_free) = (sc.is_none(), gc.is_none());
            counts[0] += 1;
            let agree = s_free == t_start && g_free == t_goal;
            counts[1] += agree as usize;
            counts[2] += !(s_free && g_free) as usize;
            counts[3] += !(t_start && t_goal) as usize;
            counts[4] += !(spheres.is_valid(&p.request.start) && spheres.is_valid(goal)) as usize;
            if !agree && args.verbose {
                println!(
                    "  {} {:04}: ours start {} goal {} ({}; {}), FCL start {} goal {} ({t_sc}; {t_gc})",
                    set.name,
                    p.index,
                    s_free,
                    g_free,
                    sc.map(|c| c.to_string()).unwrap_or_default(),
                    gc.map(|c| c.to_string()).unwrap_or_default(),
                    t_start,
                    t_goal
                );
            }
        }
        println!(
            "{:<24} {:>4} {:>6} {:>9.2}% {:>13} {:>14} {:>16}",
            set.name,
            counts[0],
            counts[1],
            100.0 * counts[1] as f64 / counts[0].max(1) as f64,
            counts[2],
            counts[3],
            counts[4]
        );
        lines.push((set.name.clone(), counts));
        for k in 0..5 {
            total[k] += counts[k];
        }
    }
    lines.push(("all".into(), total));
    for (name, c) in lines {
        println!(
            "RESULT validity set={name} n={} agree={} agreement={:.4} ours_refused={} truth_refused={} spheres_refused={}",
            c[0],
            c[1],
            c[1] as f64 / c[0].max(1) as f64,
            c[2],
            c[3],
            c[4]
        );
    }
    Ok(())
}
