//! Writing outputs safely: never over a command's own inputs ([`check_outputs`]), and
//! never leaving a partial output behind ([`write_atomically`] for files,
//! [`StagedFolder`] for folders).

use crate::{Error, ErrorKind, Result};
use std::io::{BufWriter, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

/// Write `path` through `write`, into a temporary file in the same folder that is
/// renamed over `path` only when `write` succeeded. On any error the temporary file
/// is removed and an existing `path` is left untouched.
pub fn write_atomically<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<&mut std::fs::File>) -> Result<()>,
{
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::new(
            ErrorKind::Io,
            format!("output folder {} does not exist", dir.display()),
        ));
    }
    let mut tmp = tempfile::Builder::new()
        .prefix(".relit-")
        .suffix(".partial")
        .tempfile_in(dir)
        .map_err(|e| Error::io(dir, "create a temporary file in", e))?;
    {
        let mut writer = BufWriter::new(tmp.as_file_mut());
        write(&mut writer)?;
        writer.flush().map_err(|e| Error::io(path, "write", e))?;
    }
    tmp.persist(path)
        .map_err(|e| Error::io(path, "rename the finished file to", e.error))?;
    Ok(())
}

/// Write bytes atomically.
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |w| {
        w.write_all(bytes).map_err(|e| Error::io(path, "write", e))
    })
}

/// Whether an output is one file or a folder the command fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    File,
    Folder,
}

/// Something a command is about to write, for [`check_outputs`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Output {
    pub path: PathBuf,
    pub kind: OutputKind,
}

impl Output {
    pub fn file(path: impl Into<PathBuf>) -> Output {
        Output {
            path: path.into(),
            kind: OutputKind::File,
        }
    }

    pub fn folder(path: impl Into<PathBuf>) -> Output {
        Output {
            path: path.into(),
            kind: OutputKind::Folder,
        }
    }
}

/// Refuse outputs that would write over any of `inputs`, before anything is written.
///
/// A file output clashes with an input that is the same file however it is reached:
/// the same path, another spelling of it (`./x`, `../dir/x`), a symbolic link either
/// way (also a dangling one that would be created as the input), or, on Unix, a hard
/// link (same device and inode). A folder output clashes with an input inside it
/// (compared after resolving links, and by the input's own directory entry, so a
/// symbolic link inside the folder counts too), with an input that is the folder
/// itself, and, on Unix, with an input that has a hard link anywhere inside the folder.
///
/// Inputs that do not exist are compared by path only: the command fails on reading
/// them anyway. The error names both paths as they were given.
pub fn check_outputs<P: AsRef<Path>>(inputs: &[P], outputs: &[Output]) -> Result<()> {
    if outputs.is_empty() || inputs.is_empty() {
        return Ok(());
    }
    let inputs: Vec<(&Path, Resolved)> = inputs
        .iter()
        .map(|p| (p.as_ref(), Resolved::new(p.as_ref())))
        .collect();
    for output in outputs {
        let out = Resolved::new(&output.path);
        for (input, inp) in &inputs {
            let clash = match output.kind {
                OutputKind::File => file_clash(&out, inp),
                OutputKind::Folder => folder_clash(&out, inp),
            };
            if let Some(why) = clash {
                let shown = output.path.display();
                let message = match output.kind {
                    OutputKind::File => format!(
                        "refusing to write {shown}: it would replace the input {} ({why}); nothing was written",
                        input.display()
                    ),
                    OutputKind::Folder => format!(
                        "refusing to write into the folder {shown}: {why} the input {}; nothing was written",
                        input.display()
                    ),
                };
                return Err(Error::new(ErrorKind::InvalidInput, message));
            }
        }
    }
    Ok(())
}

fn file_clash(out: &Resolved, input: &Resolved) -> Option<String> {
    if out.entry == input.entry {
        return Some("the same file".into());
    }
    if out.real == input.real || out.real == input.entry || out.entry == input.real {
        return Some(format!("both lead to {}", out.real.display()));
    }
    match (&out.id, &input.id) {
        (Some(a), Some(b)) if a.same_file(b) => Some("hard links to the same file".into()),
        _ => None,
    }
}

fn folder_clash(folder: &Resolved, input: &Resolved) -> Option<String> {
    if input.real == folder.real || input.entry == folder.real {
        return Some("it is".into());
    }
    if input.real.starts_with(&folder.real) || input.entry.starts_with(&folder.real) {
        let inside = if input.real.starts_with(&folder.real) {
            &input.real
        } else {
            &input.entry
        };
        return Some(format!("it holds {}, which is", inside.display()));
    }
    // A hard link inside the folder is the input under another name; looked for only
    // when the input has several names, so the common case costs no folder walk.
    let id = input.id.as_ref().filter(|id| id.links > 1)?;
    let found = find_hard_link(&folder.real, id)?;
    Some(format!("it holds {}, a hard link to", found.display()))
}

/// Most entries [`find_hard_link`] looks at: enough for any output folder a command
/// is pointed at on purpose, and a bound when it is pointed at a home folder.
const HARD_LINK_SEARCH_LIMIT: usize = 100_000;

fn find_hard_link(folder: &Path, id: &FileId) -> Option<PathBuf> {
    let mut pending = vec![folder.to_path_buf()];
    let mut seen = 0usize;
    while let Some(dir) = pending.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            seen += 1;
            if seen > HARD_LINK_SEARCH_LIMIT {
                return None;
            }
            let Ok(meta) = entry.metadata() else { continue };
            if meta.is_dir() {
                pending.push(entry.path());
            } else if FileId::of(&meta).is_some_and(|other| other.same_file(id)) {
                return Some(entry.path());
            }
        }
    }
    None
}

/// Where a path leads, for comparing it with others.
#[derive(Debug)]
struct Resolved {
    /// The path with every symbolic link resolved, absolute; the parts that do not
    /// exist yet are appended as written (`.` and `..` folded).
    real: PathBuf,
    /// The path's own directory entry: its folder resolved, its name kept. It differs
    /// from `real` when the path is a symbolic link.
    entry: PathBuf,
    /// The file it reaches, when it exists.
    id: Option<FileId>,
}

impl Resolved {
    fn new(path: &Path) -> Resolved {
        let real = resolve(path);
        let entry = match (path.parent(), path.file_name()) {
            (Some(parent), Some(name)) => {
                let parent = if parent.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    parent
                };
                resolve(parent).join(name)
            }
            _ => real.clone(),
        };
        let id = std::fs::metadata(path).ok().and_then(|m| FileId::of(&m));
        Resolved { real, entry, id }
    }
}

/// A file's identity: device and inode, and how many names it has.
#[derive(Debug)]
struct FileId {
    device: u64,
    inode: u64,
    links: u64,
}

impl FileId {
    #[cfg(unix)]
    fn of(meta: &std::fs::Metadata) -> Option<FileId> {
        use std::os::unix::fs::MetadataExt;
        Some(FileId {
            device: meta.dev(),
            inode: meta.ino(),
            links: meta.nlink(),
        })
    }

    /// Elsewhere files are compared by resolved path only.
    #[cfg(not(unix))]
    fn of(_meta: &std::fs::Metadata) -> Option<FileId> {
        None
    }

    fn same_file(&self, other: &FileId) -> bool {
        (self.device, self.inode) == (other.device, other.inode)
    }
}

/// Symbolic links followed before a chain is taken to be a loop (as the kernel does).
const MAX_LINK_HOPS: usize = 40;

/// `path` made absolute with every symbolic link resolved, like `canonicalize`, but
/// also for paths that do not exist yet: their missing parts are appended as written,
/// and a dangling link is followed to where it points.
fn resolve(path: &Path) -> PathBuf {
    if let Ok(real) = std::fs::canonicalize(path) {
        return real;
    }
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    let mut hops = 0;
    resolve_from(PathBuf::new(), &absolute, &mut hops)
}

fn resolve_from(mut out: PathBuf, path: &Path, hops: &mut usize) -> PathBuf {
    for component in path.components() {
        match component {
            Component::Prefix(_) | Component::RootDir => out.push(component),
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            Component::Normal(name) => {
                out.push(name);
                if let Ok(real) = std::fs::canonicalize(&out) {
                    out = real;
                } else if let Ok(target) = std::fs::read_link(&out) {
                    if *hops < MAX_LINK_HOPS {
                        *hops += 1;
                        out.pop();
                        out = resolve_from(out, &target, hops);
                    }
                }
            }
        }
    }
    out
}

/// A folder of outputs that appears complete or not at all.
///
/// Files are written into a hidden staging folder (`.relit-…`) and moved into place by
/// [`StagedFolder::commit`]:
///
/// * when the target does not exist yet, the staging folder sits beside it (missing
///   parent folders are created) and becomes the target in one rename;
/// * when it exists (an empty folder, an earlier run's output), the staging folder sits
///   inside it and each finished file is renamed over its namesake, in the order the
///   files were asked for; files of the target this run does not write are kept.
///
/// Dropped without a commit (an error, a panic), it removes the staging folder and the
/// parent folders it created, so the target is left exactly as it was. A process
/// killed outright can leave the hidden staging folder behind, never a visible file.
#[derive(Debug)]
pub struct StagedFolder {
    target: PathBuf,
    staging: PathBuf,
    /// Parent folders created for a new target, deepest first (removed on failure).
    created_parents: Vec<PathBuf>,
    /// Whether the target existed: then files are moved in one by one.
    into_existing: bool,
    /// Relative names handed out by [`StagedFolder::file`], in order.
    files: Mutex<Vec<PathBuf>>,
    committed: bool,
}

impl StagedFolder {
    /// Prepare to write the folder `target` (see the type's docs).
    pub fn new(target: &Path) -> Result<StagedFolder> {
        let into_existing = match std::fs::metadata(target) {
            Ok(meta) if meta.is_dir() => true,
            Ok(_) => {
                return Err(Error::new(
                    ErrorKind::Io,
                    format!("{} exists and is not a folder", target.display()),
                ))
            }
            Err(_) => false,
        };
        let mut created_parents = Vec::new();
        let staging_in = if into_existing {
            target.to_path_buf()
        } else {
            let parent = match target.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => PathBuf::from("."),
            };
            let mut missing = parent.as_path();
            while !missing.as_os_str().is_empty() && std::fs::symlink_metadata(missing).is_err() {
                created_parents.push(missing.to_path_buf());
                missing = missing.parent().unwrap_or(Path::new(""));
            }
            std::fs::create_dir_all(&parent)
                .map_err(|e| Error::io(&parent, "create the folder", e))?;
            parent
        };
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let staging = tempfile::Builder::new()
            .prefix(&format!(".relit-{name}-"))
            .suffix(".partial")
            .tempdir_in(&staging_in);
        let staging = match staging {
            Ok(dir) => dir.keep(),
            Err(e) => {
                remove_created(&created_parents);
                return Err(Error::io(&staging_in, "create a temporary folder in", e));
            }
        };
        Ok(StagedFolder {
            target: target.to_path_buf(),
            staging,
            created_parents,
            into_existing,
            files: Mutex::new(Vec::new()),
            committed: false,
        })
    }

    /// The folder the files will be in after the commit.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Where to write the file `name` (relative to the target, subfolders allowed and
    /// created now) before the commit.
    pub fn file(&self, name: impl AsRef<Path>) -> Result<PathBuf> {
        let name = name.as_ref();
        if !name.components().all(|c| matches!(c, Component::Normal(_))) {
            return Err(Error::invalid(format!(
                "output name {} must be relative, without `..`",
                name.display()
            )));
        }
        let path = self.staging.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| Error::io(parent, "create the folder", e))?;
        }
        self.files
            .lock()
            .expect("staged file list")
            .push(name.to_path_buf());
        Ok(path)
    }

    /// Move the finished files into place (see the type's docs).
    pub fn commit(mut self) -> Result<()> {
        if !self.into_existing {
            std::fs::rename(&self.staging, &self.target)
                .map_err(|e| Error::io(&self.target, "rename the finished folder to", e))?;
            self.committed = true;
            return Ok(());
        }
        let files = std::mem::take(&mut *self.files.lock().expect("staged file list"));
        // A folder where a file goes is the one rename that is bound to fail: found
        // before any file moves, it leaves the target untouched.
        if let Some(blocked) = files
            .iter()
            .map(|name| self.target.join(name))
            .find(|to| std::fs::symlink_metadata(to).is_ok_and(|m| m.is_dir()))
        {
            return Err(Error::new(
                ErrorKind::Io,
                format!(
                    "cannot write {}: a folder of that name is in the way",
                    blocked.display()
                ),
            ));
        }
        for name in &files {
            let from = self.staging.join(name);
            if !from.exists() {
                continue; // asked for but not written
            }
            let to = self.target.join(name);
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent)
                    .map_err(|e| Error::io(parent, "create the folder", e))?;
            }
            std::fs::rename(&from, &to)
                .map_err(|e| Error::io(&to, "rename the finished file to", e))?;
        }
        self.committed = true;
        std::fs::remove_dir_all(&self.staging)
            .map_err(|e| Error::io(&self.staging, "remove the temporary folder", e))
    }
}

impl Drop for StagedFolder {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        remove_created(&self.created_parents);
    }
}

/// Remove folders this run created (deepest first) while they are still empty.
fn remove_created(folders: &[PathBuf]) {
    for folder in folders {
        if std::fs::remove_dir(folder).is_err() {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failure_leaves_nothing_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        let err = write_atomically(&path, |w| {
            w.write_all(b"half").unwrap();
            Err(Error::invalid("boom"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary file left behind"
        );
        write_bytes_atomically(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
    }

    fn refused(inputs: &[&Path], output: Output) -> String {
        match check_outputs(inputs, std::slice::from_ref(&output)) {
            Ok(()) => panic!("{output:?} over {inputs:?} should be refused"),
            Err(e) => {
                assert_eq!(e.kind(), ErrorKind::InvalidInput);
                e.to_string()
            }
        }
    }

    #[test]
    fn a_file_output_may_not_be_an_input_under_any_name() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("sub")).unwrap();
        let input = d.join("scene.exr");
        std::fs::write(&input, b"maps").unwrap();

        let message = refused(&[&input], Output::file(&input));
        assert!(message.contains(&input.display().to_string()), "{message}");
        let spelled = d.join("sub/../././scene.exr");
        let message = refused(&[&input], Output::file(&spelled));
        assert!(
            message.contains(&spelled.display().to_string())
                && message.contains(&input.display().to_string()),
            "names both paths: {message}"
        );
        #[cfg(unix)]
        {
            let hard = d.join("sub/hard.exr");
            std::fs::hard_link(&input, &hard).unwrap();
            assert!(refused(&[&input], Output::file(&hard)).contains("hard link"));
            assert!(refused(&[&hard], Output::file(&input)).contains("hard link"));

            let link = d.join("link.exr");
            std::os::unix::fs::symlink(&input, &link).unwrap();
            refused(&[&input], Output::file(&link));
            refused(&[&link], Output::file(&input));
            // A dangling link that writing would resolve to a (missing) input's path.
            let dangling = d.join("dangling.exr");
            std::os::unix::fs::symlink(d.join("later.exr"), &dangling).unwrap();
            refused(&[&d.join("later.exr")], Output::file(&dangling));
            // A folder reached through a link.
            let sub_link = d.join("sublink");
            std::os::unix::fs::symlink(d, &sub_link).unwrap();
            refused(&[&input], Output::file(sub_link.join("scene.exr")));
        }
        // Relative spellings resolve against the working folder.
        let cwd = std::env::current_dir().unwrap();
        let relative = Path::new("Cargo.toml");
        refused(&[&cwd.join(relative)], Output::file(relative));

        // Other files, also missing ones and look-alike names, are fine.
        check_outputs(&[&input], &[Output::file(d.join("scene.exr.png"))]).unwrap();
        check_outputs(&[&input], &[Output::file(d.join("sub/scene.exr"))]).unwrap();
        check_outputs(&[&input], &[Output::file(d.join("missing/x.exr"))]).unwrap();
        check_outputs::<&Path>(&[], &[Output::file(&input)]).unwrap();
    }

    #[test]
    fn a_folder_output_may_not_hold_an_input() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let out = d.join("out");
        std::fs::create_dir_all(out.join("deep")).unwrap();
        let inside = out.join("deep/rig.json");
        std::fs::write(&inside, b"{}").unwrap();
        let outside = d.join("outside.exr");
        std::fs::write(&outside, b"maps").unwrap();

        let message = refused(&[&outside, &inside], Output::folder(&out));
        assert!(
            message.contains(&out.display().to_string())
                && message.contains(&inside.display().to_string()),
            "{message}"
        );
        refused(&[&inside], Output::folder(d.join("out/./deep/..")));
        refused(&[&outside], Output::folder(d));
        // The input itself given as the folder.
        refused(&[&outside], Output::folder(&outside));
        // A folder that does not exist yet holds nothing; a sibling with a longer name
        // is not inside.
        check_outputs(
            &[&outside, &inside],
            &[Output::folder(d.join("new/frames"))],
        )
        .unwrap();
        check_outputs(&[&d.join("out2/x")], &[Output::folder(&out)]).unwrap();
        check_outputs(&[&outside], &[Output::folder(&out)]).unwrap();
        #[cfg(unix)]
        {
            // The folder through a link, an input linking into it, a link inside it
            // pointing out, and a hard link of an input inside it.
            let out_link = d.join("out-link");
            std::os::unix::fs::symlink(&out, &out_link).unwrap();
            refused(&[&inside], Output::folder(&out_link));
            let into = d.join("into.json");
            std::os::unix::fs::symlink(&inside, &into).unwrap();
            refused(&[&into], Output::folder(&out));
            let pointing_out = out.join("maps.exr");
            std::os::unix::fs::symlink(&outside, &pointing_out).unwrap();
            refused(&[&pointing_out], Output::folder(&out));
            std::fs::remove_file(&pointing_out).unwrap();
            std::fs::hard_link(&outside, out.join("deep/frame_0000.png")).unwrap();
            let message = refused(&[&outside], Output::folder(&out));
            assert!(message.contains("hard link"), "{message}");
        }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_new_staged_folder_appears_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a/b/frames");
        {
            let staged = StagedFolder::new(&target).unwrap();
            std::fs::write(staged.file("frame_0.png").unwrap(), b"0").unwrap();
            std::fs::write(staged.file("sub/frame_1.png").unwrap(), b"1").unwrap();
            assert!(!target.exists(), "nothing visible before the commit");
            // Dropped: a failure part-way.
        }
        assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));

        let staged = StagedFolder::new(&target).unwrap();
        std::fs::write(staged.file("frame_0.png").unwrap(), b"0").unwrap();
        std::fs::write(staged.file("sub/frame_1.png").unwrap(), b"1").unwrap();
        assert!(staged.file("../escape").is_err());
        staged.commit().unwrap();
        assert_eq!(names(&target), ["frame_0.png", "sub"]);
        assert_eq!(std::fs::read(target.join("sub/frame_1.png")).unwrap(), b"1");
        assert_eq!(names(&target.join("..")), ["frames"]);
    }

    #[test]
    fn an_existing_folder_keeps_its_files_until_the_commit() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path();
        std::fs::write(target.join("frame_0.png"), b"old").unwrap();
        std::fs::write(target.join("notes.txt"), b"mine").unwrap();
        {
            let staged = StagedFolder::new(target).unwrap();
            std::fs::write(staged.file("frame_0.png").unwrap(), b"new").unwrap();
        }
        assert_eq!(names(target), ["frame_0.png", "notes.txt"]);
        assert_eq!(std::fs::read(target.join("frame_0.png")).unwrap(), b"old");

        let staged = StagedFolder::new(target).unwrap();
        std::fs::write(staged.file("frame_0.png").unwrap(), b"new").unwrap();
        std::fs::write(staged.file("more/frame_1.png").unwrap(), b"1").unwrap();
        staged.commit().unwrap();
        assert_eq!(names(target), ["frame_0.png", "more", "notes.txt"]);
        assert_eq!(std::fs::read(target.join("frame_0.png")).unwrap(), b"new");

        // A folder in the way of a file fails the commit before any file moves.
        std::fs::create_dir(target.join("frame_1.png")).unwrap();
        let staged = StagedFolder::new(target).unwrap();
        std::fs::write(staged.file("frame_0.png").unwrap(), b"newer").unwrap();
        std::fs::write(staged.file("frame_1.png").unwrap(), b"1").unwrap();
        let err = staged.commit().unwrap_err().to_string();
        assert!(err.contains("frame_1.png"), "{err}");
        assert_eq!(std::fs::read(target.join("frame_0.png")).unwrap(), b"new");
        assert_eq!(
            names(target),
            ["frame_0.png", "frame_1.png", "more", "notes.txt"]
        );

        std::fs::write(dir.path().join("file"), b"x").unwrap();
        assert!(StagedFolder::new(&dir.path().join("file")).is_err());
    }
}
