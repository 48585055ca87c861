//! Tools that measure rather than make: the accuracy of `A + GCM` against
//! the exact model, orthophotos compared with a truth, maps of the error
//! and of the matrix, and the accuracy table of an RPC grid.

pub mod accuracy;
pub mod compare;
pub mod maps;
pub mod rpc_grid;
