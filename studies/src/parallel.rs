//! A study's independent runs on worker threads: progress as they finish, results in job order.

use std::sync::{mpsc, Mutex};

/// `run` applied to every job on `workers` threads; a line `{what}: {done}/{n} runs ({s} s)`
/// every `every` finished runs and at the last; the results in the order of `jobs`. A worker
/// that panicked is an error naming `what`.
pub fn in_order<J: Send, R: Send>(
    what: &str,
    jobs: Vec<J>,
    workers: usize,
    every: usize,
    run: impl Fn(J) -> R + Sync,
) -> Result<Vec<R>, String> {
    let n = jobs.len();
    let queue = Mutex::new(jobs.into_iter().enumerate().rev().collect::<Vec<_>>());
    let started = std::time::Instant::now();
    let mut results: Vec<Option<R>> = (0..n).map(|_| None).collect();
    std::thread::scope(|s| {
        let (tx, rx) = mpsc::channel();
        let handles: Vec<_> = (0..workers.max(1))
            .map(|_| {
                let (queue, run, tx) = (&queue, &run, tx.clone());
                s.spawn(move || loop {
                    let Some((i, job)) = queue.lock().expect("queue").pop() else {
                        break;
                    };
                    if tx.send((i, run(job))).is_err() {
                        break;
                    }
                })
            })
            .collect();
        drop(tx);
        for (done, (i, r)) in rx.iter().enumerate() {
            results[i] = Some(r);
            if (done + 1) % every.max(1) == 0 || done + 1 == n {
                println!(
                    "{what}: {}/{n} runs ({:.0} s)",
                    done + 1,
                    started.elapsed().as_secs_f64()
                );
            }
        }
        for h in handles {
            h.join().map_err(|_| format!("a {what} worker panicked"))?;
        }
        Ok::<(), String>(())
    })?;
    Ok(results
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect())
}

/// A study command's `[--only TEXT]` (`command` names it in errors): the jobs whose `name`
/// contains TEXT (all without it), and TEXT.
pub fn only<'a, J>(
    command: &str,
    args: &'a [String],
    jobs: Vec<J>,
    name: impl Fn(&J) -> String,
) -> Result<(Vec<J>, Option<&'a str>), String> {
    let only = match args {
        [] => None,
        [flag, text] if flag == "--only" => Some(text.as_str()),
        _ => return Err(format!("{command}: usage: {command} [--only TEXT]")),
    };
    let Some(text) = only else {
        return Ok((jobs, None));
    };
    let example = jobs.first().map(&name).unwrap_or_default();
    let chosen: Vec<J> = jobs
        .into_iter()
        .filter(|j| name(j).contains(text))
        .collect();
    if chosen.is_empty() {
        return Err(format!(
            "{command}: no run's name contains '{text}' (names are like '{example}')"
        ));
    }
    Ok((chosen, only))
}

#[cfg(test)]
mod tests {
    /// Results come back in job order whatever the order the workers finish in.
    #[test]
    fn results_are_in_job_order() {
        let jobs: Vec<u64> = (0..40).collect();
        let out = super::in_order("test", jobs, 3, 10, |k| {
            std::thread::sleep(std::time::Duration::from_micros((40 - k) * 50));
            k * k
        })
        .unwrap();
        assert_eq!(out, (0..40).map(|k| k * k).collect::<Vec<_>>());
    }

    #[test]
    fn a_panicking_worker_is_an_error() {
        let e = super::in_order("test", vec![1, 2, 3], 2, 1, |k: i32| {
            assert!(k != 2, "job 2 fails");
            k
        })
        .unwrap_err();
        assert!(e.contains("test worker panicked"), "{e}");
    }
}
