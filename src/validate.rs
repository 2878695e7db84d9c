//! What `agglo validate` says of a scenario: what it describes, the pipeline it will run
//! and why the other systems are left out, its checkpoints and the memory it needs. The
//! command line prints it; the Python module returns it (and shows it as HTML).

use anyhow::Context;

use crate::readable::sci;
use crate::scenario::Scenario;
use crate::schedule::Pipeline;

/// The report on a valid scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationReport {
    /// What `agglo validate` prints on stdout, line by line.
    pub text: String,
    /// The memory warning it prints on stderr, if the run is large for this machine.
    pub warning: Option<String>,
    /// The pipeline the scene runs.
    pub pipeline: Pipeline,
}

/// Check `s` as a run would (pipeline, memory) and describe it. An error names what is
/// wrong: a scene that cannot be built, or one that cannot fit in memory.
pub fn report(s: &Scenario) -> anyhow::Result<ValidationReport> {
    let mut text = format!(
        "{}: valid — N = {}, b0 = {:e} m, volume fraction {:.4}, D = {} m, T = {} s, seed {}\n",
        s.name,
        s.cloud.count,
        s.primary_radius(),
        s.volume_fraction(),
        sci(s.domain.half_width),
        sci(s.time.end),
        s.seed
    );
    let pipeline = s.pipeline().context("building the scene's pipeline")?;
    text += &pipeline_text(&pipeline);
    if let Some(restart) = &s.output.restart {
        let before_end = (s.time.end / restart.every).ceil() as u64 - 1;
        text += &format!(
            "restart checkpoints: every {} s of simulated time, {before_end} before T \
             (agglo run --resume continues from the last one)\n",
            sci(restart.every)
        );
    }
    let memory = crate::memory::MemoryEstimate::of(s);
    text += &memory.describe();
    text.push('\n');
    let warning = memory.check().map_err(anyhow::Error::msg)?;
    Ok(ValidationReport {
        text,
        warning,
        pipeline,
    })
}

/// The pipeline as `validate` prints it: the core and why, the systems in order, and
/// why each other system is left out.
pub fn pipeline_text(p: &Pipeline) -> String {
    let mut text = format!("core: {} — {}\n", p.core, p.core_reason);
    text += &format!("pipeline ({} systems, in order):\n", p.systems.len());
    for (i, system) in p.systems.iter().enumerate() {
        text += &format!("  {:>2}. {system}\n", i + 1);
    }
    for line in &p.forces {
        text += &format!("{line}\n");
    }
    if p.left_out.is_empty() {
        text += "left out: nothing\n";
    } else {
        text += "left out:\n";
        for line in &p.left_out {
            text += &format!("  - {line}\n");
        }
    }
    text
}
