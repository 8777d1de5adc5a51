//! Queries between shapes: GJK distance, the time of impact, ray entry, and casts through the
//! static world.

pub(crate) mod cast;
pub(crate) mod entry;
pub(crate) mod gjk;
pub(crate) mod ray;
pub(crate) mod toi;
