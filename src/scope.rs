//! How a run covers its scene: the one home of `RunScope`, which both the
//! plain run (`crate::run`) and the runs it hands a scene to (the stall
//! search, `crate::stall::run`) read, so that neither imports the other's
//! folder back.

use crate::output::ShardSpec;
use crate::progress::ProgressMode;

/// How a run covers its scene.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunScope {
    /// Run only this shard of the instances.
    pub shard: Option<ShardSpec>,
    /// Continue an interrupted run from its checkpoint.
    pub resume: bool,
    /// Instances per chunk (the checkpoint granularity) instead of the
    /// backend's choice.
    pub chunk_size: Option<usize>,
    /// Rerun every instance 100 times tighter and mark the unconverged
    /// ones (status 5).
    pub verify: bool,
    /// How progress is shown on stderr [default: the bar on a terminal,
    /// else nothing].
    pub progress: Option<ProgressMode>,
}
