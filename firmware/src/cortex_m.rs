//! What both Cortex-M images (the 64 KiB one and the STM32F405 board) share: the stack painted
//! to measure how deep it went, and SysTick's clock with its calibration into instructions.

pub mod stack;
pub mod systick;
