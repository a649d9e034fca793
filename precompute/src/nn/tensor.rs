//! Devices and host ↔ tensor conversions.

use burn::tensor::{Device, Tensor, TensorData};

/// The device training runs on: burn's pure-Rust CPU backend with autodiff.
#[must_use]
pub fn train_device() -> Device {
    Device::flex().autodiff()
}

/// The device for inference without gradients (baking, checks).
#[must_use]
pub fn infer_device() -> Device {
    Device::flex()
}

/// A 2-D tensor from host values.
#[must_use]
pub fn tensor2(v: Vec<f32>, rows: usize, cols: usize, device: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(v, [rows, cols]), device)
}

/// A tensor's values on the host.
#[must_use]
pub fn to_host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .try_into_vec::<f32>()
        .expect("float tensors hold f32 values")
}
