//! The per-body solver: the targets and their hierarchy (`static_set`), the bounds that rule
//! pairs out (`cull`), one pair's time of impact (`pair`), the contact impulse (`response`),
//! one body's step (`body_solver`), the sensors' crossings (`sensor`), and bodies against
//! bodies ordered in time (`bodies`, with the impulse between two masses in `mutual`).

pub(crate) mod bodies;
pub(crate) mod body_solver;
pub(crate) mod cull;
pub(crate) mod mutual;
pub(crate) mod pair;
pub(crate) mod response;
pub(crate) mod sensor;
pub(crate) mod static_set;
