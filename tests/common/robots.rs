//! The test robots several tests share, each defined once as a file in `tests/data/robots/`
//! (the elastic plugin's tests read the same files). Robots one test builds by editing text,
//! and deliberately malformed ones, stay beside their test.

/// A two-link arm in the vertical plane with point masses (`planar-2r.toml`).
pub const PLANAR_2R: &str = include_str!("../data/robots/planar-2r.toml");

/// A one-joint pendulum in the vertical plane, 10 kg at 1 m (`pendulum.toml`); no error models.
pub const PENDULUM: &str = include_str!("../data/robots/pendulum.toml");
