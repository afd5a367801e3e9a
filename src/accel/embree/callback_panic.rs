//! Panics in the Rust code Embree calls back (the device's error callback,
//! `record_error` in `device.rs`, is the only such code): caught before
//! they reach C, kept, and raised again on the Rust side once the call into
//! Embree has returned, payload intact (as git2-rs does for libgit2).
//!
//! Promises:
//! - No panic unwinds into Embree: a callback's body runs inside
//!   [`catch`], which returns `None` where the body panicked.
//! - A caught panic is raised again: its payload waits in a slot of the thread
//!   the callback ran on, which is the thread that called Embree (Embree
//!   reports an error from the API call that failed, on its caller's
//!   thread), until [`resume`] raises it with `resume_unwind`. Every
//!   wrapper calls `resume` after its calls into Embree and before it
//!   returns, directly or through `Device::take_error`; `Drop` impls do not
//!   (a panic raised while unwinding would abort), so a panic caught while
//!   a `drop` releases or re-commits waits for the thread's next wrapper
//!   call, as an error reported there waits in the device's error slot (a
//!   thread that makes no further call drops it when it exits).
//! - While a panic waits, callbacks on its thread do not run (`catch`
//!   returns `None` at once), so the panic raised is the first one.
//! - Checking costs a thread-local read, cheap enough to do after every
//!   call, rays included.

use std::any::Any;
use std::cell::RefCell;
use std::panic::{self, AssertUnwindSafe};

/// A panic payload, as `catch_unwind` returns it.
type Payload = Box<dyn Any + Send + 'static>;

thread_local! {
    /// The panic a callback on this thread caught and nobody raised yet.
    static CAUGHT: RefCell<Option<Payload>> = const { RefCell::new(None) };
}

/// Runs `callback` (the body of a function Embree calls) without letting a
/// panic out: `Some` of its result, or `None` if it panicked (the payload
/// is kept for [`resume`]) or if a panic on this thread is already waiting
/// (then `callback` does not run).
pub(super) fn catch<R>(callback: impl FnOnce() -> R) -> Option<R> {
    if CAUGHT
        .try_with(|caught| caught.borrow().is_some())
        .unwrap_or(false)
    {
        return None;
    }
    // AssertUnwindSafe: the panic is raised again, so state the callback
    // left half-updated is seen only as after any panic. (The error slot it
    // writes is a Mutex whose readers accept poisoning.)
    match panic::catch_unwind(AssertUnwindSafe(callback)) {
        Ok(result) => Some(result),
        Err(payload) => {
            keep(payload);
            None
        }
    }
}

fn keep(payload: Payload) {
    let kept = CAUGHT.try_with(|caught| {
        caught.borrow_mut().get_or_insert(payload);
    });
    if kept.is_err() {
        // This thread is exiting and its slot is already gone (Embree was
        // called from a thread-local's destructor): there is nowhere to keep
        // the panic and no unwinding into C, so abort, as Rust itself does
        // for a panic in a thread-local's destructor.
        std::process::abort();
    }
}

/// Raises, with its original payload, the panic a callback on this thread
/// caught since the last call; returns if there is none.
pub(super) fn resume() {
    let waiting = CAUGHT
        .try_with(|caught| caught.borrow_mut().take())
        .ok()
        .flatten();
    if let Some(payload) = waiting {
        panic::resume_unwind(payload);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(payload: &Payload) -> &str {
        payload
            .downcast_ref::<&str>()
            .copied()
            .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
            .unwrap_or("<not a string>")
    }

    /// Stands for a call into C: runs the "callback" the way Embree would,
    /// unable to unwind, and returns normally whatever it did.
    fn c_call(callback: impl FnOnce() -> u32) -> u32 {
        catch(callback).unwrap_or(0)
    }

    #[test]
    fn a_callback_panic_reaches_the_caller_after_the_call_returns() {
        let outcome = panic::catch_unwind(|| {
            let returned = c_call(|| panic!("callback failed"));
            // The call returned normally: the panic did not unwind through it.
            assert_eq!(returned, 0);
            resume();
        });
        let payload = outcome.expect_err("the panic reaches the caller");
        assert_eq!(message(&payload), "callback failed");
        // Raised once: nothing waits any more.
        resume();
        assert_eq!(c_call(|| 7), 7);
    }

    #[test]
    fn the_first_panic_is_raised_and_later_callbacks_do_not_run() {
        let mut ran = false;
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| {
            c_call(|| panic!("first"));
            c_call(|| {
                ran = true;
                panic!("second")
            });
            resume();
        }));
        assert_eq!(message(&outcome.unwrap_err()), "first");
        assert!(!ran, "a callback ran while a panic was waiting");
    }

    #[test]
    fn without_a_panic_resume_returns_and_results_pass_through() {
        assert_eq!(catch(|| 42), Some(42));
        resume();
    }

    #[test]
    fn a_panic_waits_on_the_thread_whose_callback_caught_it() {
        let raised_there = std::thread::spawn(|| {
            c_call(|| panic!("elsewhere"));
            panic::catch_unwind(resume).is_err()
        })
        .join()
        .unwrap();
        assert!(raised_there);
        // Not this thread's: nothing to raise here.
        resume();
    }
}
