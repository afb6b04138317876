//! The parallel driver of `compensate` for G-code: lines parsed and blocks
//! refined on the pool, committed and written in order, chunk by chunk, so
//! memory stays flat.

use super::refine::{Refined, refine};
use super::solver::{BlockRecord, CompensatingSolver};
use crate::machine::chain::{JointValues, Pose};
use crate::post::{GcodeConverter, PendingPose, PostOptions, PostStats};
use std::io::{BufRead, Write};

/// How many lines ahead the in-order pass asks for a line's memory.
pub(super) const PREFETCH_LINES: usize = 4;

/// Asks the processor to bring the memory of `x` (a value or a slice)
/// into the cache, one 64-byte line at a time.
#[inline]
pub(super) fn prefetch_bytes<T: ?Sized>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (x as *const T).cast::<i8>();
        for off in (0..std::mem::size_of_val(x)).step_by(64) {
            // SAFETY: a prefetch is a hint that never faults, whatever the
            // address; SSE is part of x86_64.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// Asks the processor to bring `line`'s items and bytes into the cache: a
/// chunk's lines are parsed by a pool thread, so to the in-order pass they
/// usually sit in another core's cache, and each line's items are a
/// separate allocation the hardware prefetcher cannot guess.
#[inline]
pub(super) fn prefetch_line(line: &crate::gcode::Line) {
    prefetch_bytes(line.items.as_slice());
    prefetch_bytes(line.bytes.as_slice());
}

/// Lines per chunk of [`compensate_gcode`].
pub(super) const CHUNK_LINES: usize = 512;

/// A solver for [`GcodeConverter`] that is never called (the chunked driver
/// solves outside the converter).
pub(super) struct Unused;

impl crate::post::PoseSolver for Unused {
    fn solve(
        &mut self,
        _: &Pose,
        _: Option<&[f64]>,
        _: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        Err("internal: the chunked driver solves poses itself".into())
    }
}

/// One line of a chunk after the sequential first pass.
pub(super) enum Entry {
    /// Bytes to write unchanged (a range of the chunk's text buffer).
    Text(usize, usize),
    /// A pose block (the chunk's jobs are in the same order).
    Pose,
}

/// A pose block of a chunk.
pub(super) struct Job {
    line: usize,
    pending: PendingPose,
    th: JointValues,
    refined: Option<Refined>,
}

/// The buffers of a [`Chunk`] besides its lines, kept for the next chunk.
#[derive(Default)]
pub(super) struct ChunkParts {
    text: Vec<u8>,
    entries: Vec<Entry>,
    jobs: Vec<Job>,
}

/// A chunk of the program between the driver's stages.
pub(super) struct Chunk {
    /// The parsed lines.
    lines: Vec<crate::gcode::Line>,
    /// Text of the non-pose lines (ranges in `entries`).
    text: Vec<u8>,
    /// Every line of the chunk up to `stop`, in order.
    entries: Vec<Entry>,
    /// The pose blocks, in order.
    jobs: Vec<Job>,
    /// The first pass stopped at an error (raised once the lines before it
    /// are written).
    stop: Option<crate::error::Error>,
}

/// Compensates a G-code pose program, writing the machine program to `out`,
/// on every core: the result is the same for any number of threads.
///
/// The program goes through in chunks of lines, each in four stages:
///
/// 1. its lines are read (this thread) and parsed (a pool task);
/// 2. one sequential pass applies the modal state and solves the analytic IK
///    of each pose, continuing from the previous pose's theoretical solution
///    (branch choice and rotary unwinding need the order);
/// 3. the Newton refinements, independent per block, run in parallel;
/// 4. a last sequential pass applies the failure policy, backlash
///    pre-compensation and records in block order and writes the blocks.
///
/// The stages are pipelined: while the pool refines chunk *k* (stage 3) and
/// parses chunk *k + 2* (stage 1), this thread writes chunk *k − 1* (stage
/// 4), runs the first pass of chunk *k + 1* (stage 2) and reads the lines
/// after, so the in-order work overlaps the parallel work. `records` receives the per-block records after each chunk (memory
/// stays flat: at most four chunks are alive).
///
/// Unlike [`crate::post::post_gcode`] with the solver's
/// [`crate::post::PoseSolver`] interface, which continues each IK from the
/// previous block's *compensated* axes, the IK continues from the previous
/// *theoretical* solution: the two differ by the compensation (micrometres,
/// microradians), which changes neither the branch nor the turn of a rotary
/// except at an exact tie.
pub fn compensate_gcode<R: BufRead, W: Write + ?Sized>(
    machine: &crate::machine::Machine,
    solver: &mut CompensatingSolver<'_>,
    mut input: R,
    out: &mut W,
    opts: &PostOptions,
    mut progress: impl FnMut(u64),
    mut records: impl FnMut(&mut Vec<BlockRecord>) -> crate::error::Result<()>,
) -> crate::error::Result<PostStats> {
    use crate::error::Error;
    use rayon::prelude::*;
    let mut unused = Unused;
    let mut conv = GcodeConverter::new(machine, &mut unused, opts);
    // What the refinements need, apart from the solver's in-order state.
    let chain = solver.actual_chain.clone();
    let errors = solver.errors;
    let options = solver.options;
    let mut raw: Vec<Vec<u8>> = Vec::with_capacity(CHUNK_LINES);
    let mut number = 0usize;
    let mut bytes_read = 0u64;
    let mut previous_th: Option<JointValues> = None;
    let mut buf = Vec::new();
    let mut eof = false;

    // Reads the next chunk's lines into `raw`; how many (0 at the end).
    let mut read = |raw: &mut Vec<Vec<u8>>| -> crate::error::Result<usize> {
        let mut filled = 0;
        while filled < CHUNK_LINES && !eof {
            if raw.len() == filled {
                raw.push(Vec::with_capacity(128));
            }
            let b = &mut raw[filled];
            b.clear();
            match input.read_until(b'\n', b) {
                Ok(0) => eof = true,
                Ok(_) => filled += 1,
                Err(e) => return Err(Error::io(&opts.file_name, e)),
            }
        }
        Ok(filled)
    };
    // Parses the lines of `raw`, the first numbered `first`, into `lines`
    // (stage 1), reusing the lines' buffers.
    // (The lines take the raw buffers, which get the lines' old ones back.)
    let parse = |raw: &mut [Vec<u8>], first: usize, mut lines: Vec<crate::gcode::Line>| {
        lines.resize_with(raw.len(), Default::default);
        for (i, (b, line)) in raw.iter_mut().zip(lines.iter_mut()).enumerate() {
            crate::gcode::parse_line_swap(b, first + i, line);
        }
        lines
    };
    // Line vectors of written chunks, for reuse.
    let mut spare: Vec<Vec<crate::gcode::Line>> = Vec::new();
    // The other buffers of written chunks (cleared), for reuse: a chunk's
    // jobs take a few hundred kB, which a fresh vector would fault in page
    // by page and copy as it grows.
    let mut spare_parts: Vec<ChunkParts> = Vec::new();
    // Stage 2 of a parsed chunk.
    let mut first_pass = |conv: &mut GcodeConverter<'_>,
                          solver: &CompensatingSolver<'_>,
                          lines: Vec<crate::gcode::Line>,
                          parts: ChunkParts|
     -> Chunk {
        let mut chunk = Chunk {
            text: parts.text,
            entries: parts.entries,
            jobs: parts.jobs,
            stop: None,
            lines,
        };
        for (i, line) in chunk.lines.iter().enumerate() {
            if let Some(ahead) = chunk.lines.get(i + PREFETCH_LINES) {
                prefetch_line(ahead);
            }
            bytes_read += line.bytes.len() as u64;
            progress(bytes_read);
            let start = chunk.text.len();
            match conv.begin(line, &mut chunk.text) {
                Err(e) => {
                    chunk.stop = Some(e);
                    break;
                }
                Ok(None) => chunk.entries.push(Entry::Text(start, chunk.text.len())),
                Ok(Some(pending)) => {
                    match solver.theoretical(&pending.pose, previous_th.as_deref()) {
                        Ok(th) => {
                            previous_th = Some(th.clone());
                            chunk.entries.push(Entry::Pose);
                            chunk.jobs.push(Job {
                                line: i,
                                pending,
                                th,
                                refined: None,
                            });
                        }
                        Err(m) => {
                            chunk.stop = Some(conv.solve_error(line, &pending, m));
                            break;
                        }
                    }
                }
            }
        }
        chunk
    };

    // Stage 4 of a refined chunk; its first-pass error, if any, after its
    // lines are written. Gives the chunk's line vector back for reuse.
    let mut write = |conv: &mut GcodeConverter<'_>,
                     solver: &mut CompensatingSolver<'_>,
                     chunk: Chunk|
     -> crate::error::Result<(Vec<crate::gcode::Line>, ChunkParts)> {
        buf.clear();
        let mut done = chunk.jobs.iter().enumerate();
        for entry in &chunk.entries {
            match *entry {
                Entry::Text(a, b) => buf.extend_from_slice(&chunk.text[a..b]),
                Entry::Pose => {
                    let (j, job) = done.next().expect("one job per pose entry");
                    // The refinements were written on other cores.
                    if let Some(ahead) = chunk.jobs.get(j + PREFETCH_LINES) {
                        prefetch_bytes(ahead);
                    }
                    let line = &chunk.lines[job.line];
                    let refined = job.refined.as_ref().expect("refined in stage 3");
                    let solved = solver
                        .commit(&job.pending.pose, &job.th, refined, line.number)
                        .map_err(|m| conv.solve_error(line, &job.pending, m))?;
                    conv.finish(line, &job.pending, &solved, &mut buf)?;
                }
            }
        }
        out.write_all(&buf).map_err(|e| Error::io("<output>", e))?;
        records(&mut solver.records)?;
        match chunk.stop {
            Some(e) => Err(e),
            None => {
                let mut parts = ChunkParts {
                    text: chunk.text,
                    entries: chunk.entries,
                    jobs: chunk.jobs,
                };
                parts.text.clear();
                parts.entries.clear();
                parts.jobs.clear();
                Ok((chunk.lines, parts))
            }
        }
    };

    // The pipeline: while the pool refines chunk k and parses chunk k + 2,
    // this thread writes chunk k − 1 and runs the first pass of chunk k + 1.
    let mut raw_next: Vec<Vec<u8>> = Vec::with_capacity(CHUNK_LINES);
    let mut count = read(&mut raw)?;
    let mut parsed = (count > 0).then(|| parse(&mut raw[..count], 1, Vec::new()));
    number += count;
    count = read(&mut raw)?;
    let mut current: Option<Chunk> = None;
    let mut previous: Option<Chunk> = None;
    let mut stopped = false;
    while parsed.is_some() || current.is_some() || previous.is_some() {
        let first = number + 1;
        number += count;
        let mut parsed_next = None;
        let next = rayon::in_place_scope(|scope| {
            if let Some(c) = current.as_mut() {
                let (chain, options) = (&chain, &options);
                let jobs = &mut c.jobs;
                scope.spawn(move |_| {
                    jobs.par_iter_mut().for_each(|j| {
                        j.refined = Some(refine(chain, errors, &j.pending.pose, &j.th, options))
                    })
                });
            }
            if count > 0 && !stopped {
                let (lines, slot) = (&mut raw[..count], &mut parsed_next);
                let reuse = spare.pop().unwrap_or_default();
                scope.spawn(move |_| *slot = Some(parse(lines, first, reuse)));
            }
            if let Some(p) = previous.take() {
                let (lines, parts) = write(&mut conv, solver, p)?;
                spare.push(lines);
                spare_parts.push(parts);
            }
            let next = match parsed.take() {
                Some(lines) if !stopped => {
                    let parts = spare_parts.pop().unwrap_or_default();
                    Some(first_pass(&mut conv, solver, lines, parts))
                }
                _ => None,
            };
            // Read the chunk after while the pool works (the raw buffers
            // of the chunk being parsed are not touched).
            let n = if stopped { 0 } else { read(&mut raw_next)? };
            Ok::<_, crate::error::Error>((next, n))
        });
        let (next, n) = next?;
        // No chunk after one whose first pass stopped.
        stopped |= next.as_ref().is_some_and(|c| c.stop.is_some());
        previous = current.take();
        current = next;
        parsed = if stopped { None } else { parsed_next };
        std::mem::swap(&mut raw, &mut raw_next);
        count = n;
    }
    Ok(conv.stats)
}
