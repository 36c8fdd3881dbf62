//! Measurements on the emulated MCU: peak stack by painting, instructions by SysTick.
//!
//! QEMU does not model cycles. Run with `-icount shift=0`, virtual time advances exactly one
//! nanosecond per executed instruction, so SysTick (clocked by the core clock) counts
//! instructions in fixed units: [`Counter::calibrate`] measures how many instructions one tick
//! is (a loop of a known instruction count), and [`Counter::instructions`] converts. The 24-bit
//! counter runs with reload `0xFF_FFFF`; its wraps are counted in the SysTick exception.

use core::arch::asm;
use core::ptr::{addr_of, read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::exception;

/// SysTick reload value: the full 24-bit range.
const RELOAD: u32 = 0x00FF_FFFF;

/// Number of SysTick wraps so far.
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    // Load and store: Cortex-M0 has no atomic read-modify-write, and nothing else writes it.
    WRAPS.store(
        WRAPS.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Relaxed,
    );
}

/// SysTick ticks since [`Counter::start`].
pub fn ticks() -> u64 {
    loop {
        let wraps = WRAPS.load(Ordering::Relaxed);
        let current = SYST::get_current();
        if WRAPS.load(Ordering::Relaxed) == wraps {
            return (u64::from(wraps) << 24) | u64::from(RELOAD - current);
        }
    }
}

/// Runs exactly `2 * n` instructions (`subs` + `bne` per iteration), `n >= 1`.
#[inline(never)]
fn spin(n: u32) {
    // SAFETY: a register-only countdown loop.
    unsafe {
        asm!(
            "2:",
            "subs {n}, #1",
            "bne 2b",
            n = inout(reg) n => _,
            // Not `nomem`: the asm must stay a compiler barrier between the timer reads.
            options(nostack),
        );
    }
}

/// Converts SysTick ticks into instruction counts.
pub struct Counter {
    /// Instructions of the calibration loop.
    instr: u64,
    /// Ticks of the calibration loop.
    ticks: u64,
}

impl Counter {
    /// Starts SysTick (core clock, full reload, wrap interrupt) and calibrates it.
    pub fn start(mut syst: SYST) -> Counter {
        syst.set_clock_source(SystClkSource::External);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        // The counter starts at 0 and loads the reload value on its first tick: let it.
        while SYST::get_current() == 0 {}
        Counter::calibrate()
    }

    /// Times two countdown loops; their difference is exactly `2 * (N2 - N1)` instructions.
    fn calibrate() -> Counter {
        const N1: u32 = 1 << 18;
        const N2: u32 = 1 << 21;
        let t0 = ticks();
        spin(N1);
        let t1 = ticks();
        spin(N2);
        let t2 = ticks();
        let short = t1 - t0;
        let long = t2 - t1;
        Counter {
            instr: 2 * u64::from(N2 - N1),
            ticks: long.saturating_sub(short),
        }
    }

    /// Instructions per tick, times 1000 (0 when SysTick does not run).
    pub fn milli_instr_per_tick(&self) -> u64 {
        divide(self.instr * 1000, self.ticks)
    }

    /// Instructions executed in `ticks` SysTick ticks (rounded; one tick of resolution).
    pub fn instructions(&self, ticks: u64) -> u64 {
        divide(ticks * self.instr + self.ticks / 2, self.ticks)
    }

    /// Runs `call` from the caller's frame (inlined), the free stack painted before and
    /// scanned after: its result, peak stack and instructions.
    #[inline(always)]
    pub fn measure<T>(&self, call: impl FnOnce() -> T) -> Measured<T> {
        paint();
        let base = sp();
        let t0 = ticks();
        let value = call();
        let t1 = ticks();
        let stack = peak(base);
        Measured {
            value,
            stack,
            instructions: self.instructions(t1 - t0),
        }
    }
}

/// What one measured call ([`Counter::measure`]) gave and cost.
pub struct Measured<T> {
    /// The call's result.
    pub value: T,
    /// Its peak stack, in bytes.
    pub stack: usize,
    /// Its instructions.
    pub instructions: u64,
}

extern "C" {
    /// Start of the heap = end of `.bss`/`.uninit` (cortex-m-rt's linker script): the lowest
    /// address the stack can grow to.
    static __sheap: u32;
}

/// The paint pattern.
const PAINT: u32 = 0xC0DE_5AFE;

/// The current stack pointer.
#[inline(always)]
pub fn sp() -> usize {
    let sp: usize;
    // SAFETY: reads a register.
    unsafe { asm!("mov {}, sp", out(reg) sp, options(nomem, nostack, preserves_flags)) };
    sp
}

fn stack_floor() -> usize {
    (addr_of!(__sheap) as usize + 3) & !3
}

/// Paints the free stack (from the end of static RAM up to just below this function's frame)
/// with [`PAINT`]. Call it from the frame that then calls the code to measure.
#[inline(never)]
pub fn paint() {
    let top = (sp() - 16) & !3;
    let mut p = stack_floor();
    while p < top {
        // SAFETY: `[floor, top)` is free stack below the live frames; nothing else uses it.
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Peak stack used below `base` (a stack pointer read before the measured call) since the last
/// [`paint`]: `base` minus the lowest address whose paint was overwritten.
pub fn peak(base: usize) -> usize {
    let mut p = stack_floor();
    // SAFETY: reads free stack memory painted by `paint`.
    while p < base && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    base.saturating_sub(p)
}

/// Bytes of free stack (end of static RAM to `sp`).
pub fn free_stack() -> usize {
    sp().saturating_sub(stack_floor())
}

/// `n / d` (0 when `d` is 0), a bit at a time. The harness divides nowhere else and prints
/// with [`Decimal`], so that it links no division routine on a Cortex-M0 (which has no divide
/// instruction): a routine the decoder needed would then show in the decoder's flash, which the
/// bench measures against this harness.
pub fn divide(n: u64, d: u64) -> u64 {
    if d == 0 {
        return 0;
    }
    let (mut quotient, mut rest) = (0u64, 0u128);
    for bit in (0..64).rev() {
        rest = rest << 1 | u128::from(n >> bit & 1);
        if rest >= u128::from(d) {
            rest -= u128::from(d);
            quotient |= 1 << bit;
        }
    }
    quotient
}

/// An integer written in decimal by subtracting powers of ten: `core::fmt`'s integer formatting
/// divides (see [`divide`]).
pub struct Decimal(pub i64);

/// `10^19, 10^18, …, 1`.
const POWERS_OF_TEN: [u64; 20] = {
    let mut powers = [1u64; 20];
    let mut k = 19;
    while k > 0 {
        k -= 1;
        powers[k] = powers[k + 1] * 10;
    }
    powers
};

impl core::fmt::Display for Decimal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        use core::fmt::Write;
        if self.0 < 0 {
            f.write_char('-')?;
        }
        let mut n = self.0.unsigned_abs();
        // `{:0N}`: zeros up to `N` digits.
        let digits = POWERS_OF_TEN.iter().filter(|&&p| p <= n.max(1)).count();
        if f.sign_aware_zero_pad() {
            for _ in digits..f.width().unwrap_or(0) {
                f.write_char('0')?;
            }
        }
        let mut started = false;
        for (k, power) in POWERS_OF_TEN.into_iter().enumerate() {
            let mut digit = 0u8;
            while n >= power {
                n -= power;
                digit += 1;
            }
            started |= digit > 0 || k == POWERS_OF_TEN.len() - 1;
            if started {
                f.write_char(char::from(b'0' + digit))?;
            }
        }
        Ok(())
    }
}
