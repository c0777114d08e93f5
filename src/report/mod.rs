//! Tables, plots and benchmarks: error against run time, the real-data benchmark, Note S12's
//! detection limits, the array's stitching orders.

pub mod array_bench;
pub mod bench;
pub mod bench_live;
pub mod bench_real;
pub mod detection_limits;
pub mod eval_plot;
pub mod flow_bench;
pub mod kernel_bench;
pub mod noise_fit;
pub mod refine_bench;
pub mod timing;
pub mod track_plot;
