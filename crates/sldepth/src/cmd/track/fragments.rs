//! The run's record of its fragments (`sl_track::Reconstruction`): where each starts, what it
//! tracked and fused, which one it rejoined, and its mesh, written as soon as the fragment is
//! handed over, to `--mesh` or its `.fragment-k` name.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use sl_core::WorldToWorld;
use sl_track::{Reconstruction, Step};
use sl_tsdf::MeshConfig;

use super::Args;
use crate::common::limits;

/// What the run did with one fragment.
pub(super) struct FragmentOut {
    pub(super) first_frame: usize,
    pub(super) tracked: usize,
    /// The fragment it rejoined and the transform into that one's world.
    pub(super) joined: Option<sl_track::FragmentJoin>,
    pub(super) mesh: Option<WrittenMesh>,
    /// Frames fused into its volume.
    pub(super) fused: usize,
    /// Its volume's blocks and their memory, bytes (what `--max-memory` bounds).
    pub(super) blocks: usize,
    pub(super) model_bytes: usize,
    /// The frame whose fusion found its model full (the memory budget reached).
    pub(super) model_full_at: Option<usize>,
    /// The fragment whose full model it continues, in that one's world frame.
    pub(super) continues: Option<usize>,
}

impl FragmentOut {
    pub(super) fn starting_at(first_frame: usize) -> Self {
        Self {
            first_frame,
            tracked: 0,
            joined: None,
            mesh: None,
            fused: 0,
            blocks: 0,
            model_bytes: 0,
            model_full_at: None,
            continues: None,
        }
    }

    /// The fragment it rejoined (a continuation's join to the fragment it continues is not a
    /// rejoin).
    pub(super) fn rejoined(&self) -> Option<usize> {
        self.joined
            .map(|j| j.into)
            .filter(|&into| Some(into) != self.continues)
    }

    fn finish(&mut self, done: &sl_track::Fragment, mesh: Option<WrittenMesh>) {
        self.tracked = done.tracked_frames;
        self.joined = done.joined;
        self.continues = done.continues;
        self.mesh = mesh;
        self.fused = done.volume.frame_count();
        self.blocks = done.volume.block_count();
        self.model_bytes = done.volume.memory_bytes();
    }
}

/// A fragment's mesh as written.
pub(super) struct WrittenMesh {
    pub(super) path: PathBuf,
    pub(super) vertices: usize,
    pub(super) triangles: usize,
}

/// Writes the mesh of a finished fragment (when `--mesh` was given). A mesh that cannot be
/// made or written (over the memory budget, a full disk) is said on standard error and kept
/// in `errors`: the run goes on, its trajectories are written, and it fails at the end.
fn write_fragment_mesh(
    args: &Args,
    fragment: &sl_track::Fragment,
    budget_bytes: usize,
    errors: &mut Vec<String>,
) -> Option<WrittenMesh> {
    match try_write_fragment_mesh(args, fragment, budget_bytes) {
        Ok(mesh) => mesh,
        Err(e) => {
            let e = format!("fragment {}'s mesh not written: {e:#}", fragment.index);
            errln!("error: {e}");
            errors.push(e);
            None
        }
    }
}

/// [`write_fragment_mesh`], failing.
fn try_write_fragment_mesh(
    args: &Args,
    fragment: &sl_track::Fragment,
    budget_bytes: usize,
) -> Result<Option<WrittenMesh>> {
    let Some(p) = &args.mesh else {
        return Ok(None);
    };
    let mut mesh = fragment
        .volume
        .extract_mesh_within(&MeshConfig::default(), budget_bytes)?;
    // A fragment that rejoined the one before is written in that one's world frame.
    if let Some(j) = &fragment.joined {
        mesh.transform(j.transform.isometry());
    }
    // In the data set's frame, as the trajectory (ICL-NUIM: y up).
    if args.data_y_up {
        mesh.reflect_y();
    }
    let path = fragment_path(p, fragment.index);
    sl_tsdf::io::write_mesh_ply(&path, &mesh, sl_io::ply::PlyFormat::BinaryLittleEndian)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(Some(WrittenMesh {
        path,
        vertices: mesh.vertex_count(),
        triangles: mesh.triangle_count(),
    }))
}

/// The fragment bookkeeping of frame `i`'s step: a fragment it started, the fragment it handed
/// over (meshed, beside the volumes `rec` still holds) and a model it found full, each said on
/// standard error.
pub(super) fn note_step(
    args: &Args,
    i: usize,
    step: &Step,
    rec: &Reconstruction,
    fragments: &mut Vec<FragmentOut>,
    mesh_errors: &mut Vec<String>,
) {
    if step.fragment >= fragments.len() {
        fragments.push(FragmentOut::starting_at(i));
        match step.continued {
            Some(full) => errln!(
                "frame {i}: fragment {full}'s model is full ({}): fragment {} goes on in a new volume in the same world frame",
                step.model_full.as_deref().unwrap_or("the memory budget"),
                step.fragment
            ),
            None => errln!(
                "frame {i}: lost for over {} s, fragment {} starts",
                args.new_fragment_after_s,
                step.fragment
            ),
        }
    }
    if let Some(done) = &step.finished {
        // Meshed beside the volumes still held (the current fragment's and a suspended
        // one's), within the volume-and-mesh share.
        let budget = limits()
            .mesh_budget_bytes
            .saturating_sub(rec.memory_bytes());
        let mesh = write_fragment_mesh(args, done, budget, mesh_errors);
        if let Some(out) = fragments.get_mut(done.index) {
            out.finish(done, mesh);
            if step.continued == Some(done.index) {
                out.model_full_at.get_or_insert(i);
            }
        }
        if let (Some(j), Some(p)) = (done.rejoin(), done.continues) {
            join_continued_chain(fragments, p, j, args.data_y_up, mesh_errors);
        }
        if done.index > step.fragment {
            errln!(
                "frame {i}: back in fragment {}; fragment {} ({} frames) rejoins it{}",
                step.fragment,
                done.index,
                done.tracked_frames,
                if done.joined.is_some() {
                    ""
                } else {
                    " (no frame with a pose in both: kept in its own world frame)"
                }
            );
        }
    }
    let k = step.fragment;
    if let Some(why) = step
        .model_full
        .as_ref()
        .filter(|_| step.continued.is_none())
    {
        if rec.model_full().is_none() {
            // A waiting first frame was refused and this frame started the model.
            errln!(
                "warning: frame {i}: fragment {k}'s first frame was not fused, {why}: --max-memory, --voxel-m. Its model starts with this frame"
            );
        } else if rec.volume().frame_count() == 0 {
            errln!(
                "warning: frame {i}: fragment {k}'s volume cannot hold its first frame, {why}: --max-memory, --voxel-m. Its next frames are tracked against the frame before, and each is fused if it fits"
            );
        } else {
            errln!(
                "warning: frame {i}: fragment {k}'s model is full, {why}: --max-memory, --voxel-m. Its next frames are tracked against the frame before and not fused; its mesh holds the frames before this one"
            );
        }
        if let Some(out) = fragments.get_mut(k) {
            out.model_full_at.get_or_insert(i);
        }
    }
    if let Some(out) = fragments.get_mut(k)
        && step.fused
        && out.model_full_at.is_some()
        && rec.model_full().is_none()
    {
        // An empty volume took a frame at last: the fragment is not full.
        if step.model_full.is_none() {
            errln!("frame {i}: fragment {k}'s model starts with this frame");
        }
        out.model_full_at = None;
    }
}

/// A continuation that rejoined an older fragment (`join`) shares its world frame with the
/// fragments it continues, from `from` back to the first of them: the first is joined there
/// too (their poses follow it through `world_of`), and their meshes, written before the join
/// was known, are rewritten in that world (read back within the run's limits, moved, written
/// atomically). A mesh that cannot be is said and kept in `errors`.
fn join_continued_chain(
    fragments: &mut [FragmentOut],
    from: usize,
    join: sl_track::FragmentJoin,
    y_up: bool,
    errors: &mut Vec<String>,
) {
    let chain: Vec<usize> =
        sl_track::continued_chain(from, |k| fragments.get(k).and_then(|f| f.continues)).collect();
    for &k in &chain {
        if let Some(m) = fragments.get(k).and_then(|f| f.mesh.as_ref())
            && let Err(e) = move_mesh(&m.path, &join.transform, y_up)
        {
            let e = format!(
                "fragment {k}'s mesh not moved into fragment {}'s world: {e:#}",
                join.into
            );
            errln!("error: {e}");
            errors.push(e);
        }
    }
    if let Some(first) = chain.last().and_then(|&k| fragments.get_mut(k))
        && first.joined.is_none()
    {
        first.joined = Some(join);
    }
}

/// Rewrites the mesh at `path` moved by `transform`; a mesh written in a y-up data set's
/// frame (`y_up`) is moved by the same transform seen there.
fn move_mesh(path: &Path, transform: &WorldToWorld, y_up: bool) -> Result<()> {
    let mut mesh = sl_io::ply::read_ply_with_limits(path, &limits())
        .with_context(|| format!("reading {}", path.display()))?
        .into_mesh();
    let transform = if y_up {
        transform.y_reflected()
    } else {
        *transform
    };
    mesh.transform(transform.isometry());
    sl_tsdf::io::write_mesh_ply(path, &mesh, sl_io::ply::PlyFormat::BinaryLittleEndian)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Meshes the fragments `Reconstruction::finish` handed back: each within the volume-and-mesh
/// share but what the fragments still to mesh hold.
pub(super) fn mesh_finished(
    args: &Args,
    left: Vec<sl_track::Fragment>,
    fragments: &mut [FragmentOut],
    mesh_errors: &mut Vec<String>,
) {
    let mut held: usize = left.iter().map(|f| f.volume.memory_bytes()).sum();
    let whole = limits().mesh_budget_bytes;
    for done in left {
        held -= done.volume.memory_bytes();
        let budget = whole.saturating_sub(held);
        let mesh = write_fragment_mesh(args, &done, budget, mesh_errors);
        if let Some(out) = fragments.get_mut(done.index) {
            out.finish(&done, mesh);
        }
    }
}

/// The fragment whose world frame fragment `f`'s poses are written in, and the transform there:
/// through the fragment it joined, and on through the one that one joined (a continuation is
/// joined to the fragment it continues; joins always go to an older fragment).
pub(super) fn world_of(f: usize, fragments: &[FragmentOut]) -> (usize, Option<WorldToWorld>) {
    let (mut world, mut transform) = (f, None::<WorldToWorld>);
    while let Some(j) = fragments
        .get(world)
        .and_then(|o| o.joined)
        .filter(|j| j.into < world)
    {
        transform = Some(match transform {
            Some(t) => j.transform * t,
            None => j.transform,
        });
        world = j.into;
    }
    (world, transform)
}

/// The file of fragment `fragment`: `path` itself for fragment 0, else `stem.fragment-k.ext`.
pub(super) fn fragment_path(path: &Path, fragment: usize) -> PathBuf {
    if fragment == 0 {
        return path.to_path_buf();
    }
    let stem = path.file_stem().map_or_else(
        || "output".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    let name = match path.extension() {
        Some(e) => format!("{stem}.fragment-{fragment}.{}", e.to_string_lossy()),
        None => format!("{stem}.fragment-{fragment}"),
    };
    path.with_file_name(name)
}
