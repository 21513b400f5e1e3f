//! File formats: HDF5 for arrays, Parquet for tables, XDMF sidecars for ParaView. Only the
//! pipeline does I/O; stages never open a file.

pub mod array;
pub mod h5;
pub mod model;
pub mod npy;
pub mod npz;
pub(crate) mod snapshot_set;
pub mod source;
pub mod table;
pub mod xdmf;
