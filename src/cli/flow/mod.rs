//! Commands of the MMS flow network, one file per family: training (train, export, average),
//! inference (infer, eval, refine) and the benchmarks (bench-flow, bench-real, bench-live,
//! detect-limits).

mod bench;
mod infer;
mod refine;
mod train;

pub(crate) use bench::{
    BenchFlowArgs, BenchLiveArgs, BenchRealArgs, DetectLimitsArgs, bench_flow, bench_live,
    bench_real, detect_limits,
};
pub(crate) use infer::{EvalArgs, InferArgs, eval, infer};
pub(crate) use refine::{RefineArgs, refine};
pub(crate) use train::{AverageArgs, ExportArgs, TrainArgs, average, export, train};
