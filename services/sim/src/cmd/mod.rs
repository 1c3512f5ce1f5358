pub mod calib;
pub mod render;
pub mod run;
