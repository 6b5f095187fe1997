//! The `softbody` library: what the command-line tool and the benchmark report share.
//!
//! Only the charts live here ([`plot`]): line and bar charts drawn with the report's font,
//! saved as PNG and SVG. Everything else of the tool is in the binary (`src/main.rs`).

pub mod plot;
