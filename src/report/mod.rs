//! Tables, plots and benchmarks: error against run time.

pub mod bench;
pub mod bench_real;
pub mod eval_plot;
pub mod flow_bench;
pub mod track_plot;
