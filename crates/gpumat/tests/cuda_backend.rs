//! `Cuda::new` and `CudaDevice::new` never panic: on a machine without the CUDA driver, NVRTC or a
//! device they return `Error::CudaUnavailable` with one line (this machine, CI), and with a GPU
//! they open a context (and `CudaDevice` runs a kernel of the catalogue).

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

use gpumat::cuda::launch;
use gpumat::device::{Arg, CudaDevice, DeviceBuffer};

/// `CudaDevice::new` is a value, not a panic: without the CUDA driver, NVRTC or a device it is
/// `Error::CudaUnavailable` with one line; with a GPU the device copies data both ways, runs a
/// catalogue kernel and refuses an unknown one.
#[test]
fn cuda_device_new_is_a_value_not_a_panic() {
    match CudaDevice::new(0) {
        Ok(dev) => {
            println!("CUDA device: {}", dev.name());
            assert!(dev.name().contains("sm_"), "{}", dev.name());
            let x: Vec<f64> = (0..1000).map(|i| i as f64).collect();
            let xb = DeviceBuffer::from_slice(&dev, &x).unwrap();
            assert_eq!(xb.to_vec().unwrap(), x);
            // y += alpha[b] x, one batch
            let mut yb = DeviceBuffer::<f64>::zeros(&dev, x.len()).unwrap();
            yb.upload(&vec![1.0; x.len()]).unwrap();
            let alpha = DeviceBuffer::from_slice(&dev, &[2.0f64]).unwrap();
            let args = [
                yb.arg(),
                xb.arg(),
                alpha.arg(),
                Arg::Index(x.len() as u64),
                Arg::Index(1),
            ];
            // SAFETY: gpumat_axpy_f64(y, x, alpha, n, batches) on buffers of n and 1 elements.
            unsafe { dev.launch("gpumat_axpy_f64", launch::elementwise(x.len()), &args) }.unwrap();
            dev.synchronize().unwrap();
            let y = yb.to_vec().unwrap();
            assert!(y.iter().zip(&x).all(|(y, x)| *y == 1.0 + 2.0 * x));
            // SAFETY: the kernel does not exist, so nothing is launched.
            let unknown = unsafe { dev.launch("no_such_kernel", launch::elementwise(1), &[]) };
            assert!(matches!(unknown, Err(Error::Device(_))), "{unknown:?}");
        }
        Err(e) => {
            let msg = e.to_string();
            println!("{msg}");
            assert!(matches!(e, Error::CudaUnavailable(_)), "{msg}");
            assert!(!msg.contains('\n') && msg.len() < 200, "{msg}");
        }
    }
    // an absurd ordinal is an error too, not a panic
    assert!(matches!(CudaDevice::new(1 << 20), Err(Error::CudaUnavailable(_))));
}

/// The same with NVRTC looked for in a folder without it (`GPUMAT_NVRTC_DIR`, read once per
/// process: the test above runs again in a child process).
#[test]
fn cuda_device_new_with_an_empty_nvrtc_dir() {
    if std::env::var_os("GPUMAT_CHILD").is_some() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("gpumat_no_nvrtc_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "cuda_device_new_is_a_value_not_a_panic", "--nocapture"])
        .env("GPUMAT_NVRTC_DIR", &dir)
        .env("GPUMAT_CHILD", "1")
        .output()
        .unwrap();
    let _ = std::fs::remove_dir(&dir);
    let text = String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    println!("{text}");
    assert!(out.status.success(), "{text}");
    assert!(text.contains("1 passed"), "{text}");
}
