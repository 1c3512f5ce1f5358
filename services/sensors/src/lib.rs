//! Camera and INS input for the stack. [`reader`]: recordings made by the recorder, read back in
//! log-time order for replay (the binary republishes them byte for byte). [`source`]: the trait a
//! live device driver implements.

pub mod reader;
pub mod source;

pub use reader::{Message, ReadError, Recording, Truncation};
pub use source::{Sink, Source, SourceError};
