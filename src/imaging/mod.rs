//! The camera model (Notes S4–S5, Eqs. S1–S4): a pipeline of stages built from a config.
