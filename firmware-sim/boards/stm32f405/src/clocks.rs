//! The clock tree: 168 MHz from the PLL where it locks, the 16 MHz internal oscillator where it
//! does not (QEMU), and the bus clock the USART's divisor is computed from either way.

use stm32f4::stm32f405 as pac;

/// The internal oscillator, on at reset on every STM32F4.
const HSI_HZ: u32 = 16_000_000;
/// Polls of a ready bit before giving up on it: about 2 ms at 16 MHz, where the PLL locks in
/// well under 0.5 ms (RM0090: 100 us typical).
const READY_POLLS: u32 = 10_000;

/// The clocks the part ended up with.
#[derive(Clone, Copy)]
pub struct Clocks {
    /// APB1's clock, USART2's.
    pub pclk1: u32,
    /// APB2's clock, USART1's.
    pub pclk2: u32,
}

/// Sets the PLL for 168 MHz (HSI / 16 * 336 / 2; 48 MHz for USB at /7), APB2 at 84 MHz and APB1
/// at 42 MHz, with 5 flash wait states; falls back to the internal oscillator for everything if
/// the PLL does not report lock or the switch does not take.
pub fn setup(rcc: &pac::RCC, flash: &pac::FLASH) -> Clocks {
    let hsi = Clocks {
        pclk1: HSI_HZ,
        pclk2: HSI_HZ,
    };
    // SAFETY: RM0090 6.3.2: PLLM = 16, PLLN = 336, PLLP = /2 (field 0), PLLSRC = HSI (0),
    // PLLQ = 7; reserved bits kept as at reset (bit 29 set).
    rcc.pllcfgr()
        .write(|w| unsafe { w.bits((7 << 24) | (1 << 29) | (336 << 6) | 16) });
    rcc.cr().modify(|_, w| w.pllon().set_bit());
    if !poll(|| rcc.cr().read().pllrdy().bit_is_set()) {
        rcc.cr().modify(|_, w| w.pllon().clear_bit());
        return hsi;
    }
    // 5 wait states at 168 MHz and 3.3 V (RM0090 table 10), with prefetch and both caches.
    // SAFETY: LATENCY is a 4-bit field; 5 is a defined value.
    flash.acr().modify(|_, w| unsafe {
        w.latency()
            .bits(5)
            .prften()
            .set_bit()
            .icen()
            .set_bit()
            .dcen()
            .set_bit()
    });
    // AHB /1, APB1 /4 (PPRE1 = 0b101), APB2 /2 (PPRE2 = 0b100), system clock from the PLL (SW = 2).
    // SAFETY: RM0090 6.3.3's encodings; the other fields keep their reset value 0.
    rcc.cfgr()
        .write(|w| unsafe { w.bits((0b100 << 13) | (0b101 << 10) | 0b10) });
    if !poll(|| rcc.cfgr().read().sws().bits() == 0b10) {
        // SAFETY: SW = 0: back to the internal oscillator, prescalers at /1.
        rcc.cfgr().write(|w| unsafe { w.bits(0) });
        return hsi;
    }
    Clocks {
        pclk1: 42_000_000,
        pclk2: 84_000_000,
    }
}

/// Whether `ready` came true within [`READY_POLLS`] polls.
fn poll(ready: impl Fn() -> bool) -> bool {
    (0..READY_POLLS).any(|_| ready())
}
