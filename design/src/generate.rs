//! The generated Rust source that carries the vertex gains into `dvpp-control`.
