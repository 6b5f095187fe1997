//! `Cuda::new` never panics: on a machine without the CUDA driver, NVRTC or a device it returns
//! `Error::CudaUnavailable` with one line (this machine, CI), and with a GPU it opens a context.

use gpumat::backend::{Backend, Cuda};
use gpumat::Error;

#[test]
fn cuda_new_is_a_value_not_a_panic() {
    match Cuda::new(0) {
        Ok(c) => {
            println!("CUDA backend: {}", c.name());
            assert!(c.name().starts_with("cuda"));
            c.synchronize().unwrap();
        }
        Err(e) => {
            let msg = e.to_string();
            println!("{msg}");
            assert!(matches!(e, Error::CudaUnavailable(_)), "{msg}");
            assert!(!msg.contains('\n') && msg.len() < 200, "{msg}");
        }
    }
    // an absurd ordinal is an error too, not a panic
    assert!(matches!(Cuda::new(1 << 20), Err(Error::CudaUnavailable(_))));
}
