//! Scene panel: presets, open/save RON, reset.

use std::path::{Path, PathBuf};

use eframe::egui;

use super::PanelContext;
use crate::commands::Command;

/// The `.ron` files of the `scenes/` folder (presets), sorted.
pub fn presets() -> Vec<PathBuf> {
    let mut list: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "ron")).collect()
        })
        .unwrap_or_default();
    list.sort();
    list
}

/// The `scenes/` folder: next to the working directory, or the repository's.
pub fn scenes_dir() -> PathBuf {
    let local = Path::new("scenes");
    if local.is_dir() { local.to_path_buf() } else { Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes") }
}

/// State of the small file browser used for Open and Save as.
#[derive(Default)]
pub struct FileBrowser {
    /// Open for `Some(true)` (open) or `Some(false)` (save as).
    pub mode: Option<bool>,
    /// Folder shown.
    pub dir: PathBuf,
    /// File name typed or picked.
    pub name: String,
}

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>, path: Option<&Path>, browser: &mut FileBrowser) {
    ui.horizontal(|ui| {
        ui.label("Preset");
        egui::ComboBox::from_id_salt("preset")
            .selected_text(
                path.and_then(|p| p.file_name())
                    .map(|f| f.to_string_lossy().into_owned())
                    .unwrap_or("(built-in)".into()),
            )
            .show_ui(ui, |ui| {
                for preset in presets() {
                    let name = preset.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
                    if ui.selectable_label(path == Some(preset.as_path()), name).clicked() {
                        ctx.commands.push(Command::OpenScene(preset));
                    }
                }
            });
    });
    ui.horizontal(|ui| {
        if ui.button("Open…").clicked() {
            *browser = FileBrowser { mode: Some(true), dir: scenes_dir(), name: String::new() };
        }
        let save = ui.add_enabled(path.is_some(), egui::Button::new("Save"));
        if save.clicked()
            && let Some(p) = path
        {
            ctx.commands.push(Command::SaveScene(p.to_path_buf()));
        }
        if ui.button("Save as…").clicked() {
            let name = path
                .and_then(|p| p.file_name())
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or("my-scene.ron".into());
            *browser = FileBrowser { mode: Some(false), dir: scenes_dir(), name };
        }
        if ui.button("Reset").on_hover_text("Restart the scene from its initial state").clicked() {
            ctx.commands.push(Command::Reset);
        }
    });
    ui.horizontal(|ui| {
        ui.label("Name");
        ui.text_edit_singleline(&mut ctx.scene.name);
    });
    ui.label(egui::RichText::new(&ctx.scene.description).weak());
}

/// The Open / Save-as window.
pub fn browser_window(egui_ctx: &egui::Context, browser: &mut FileBrowser, commands: &mut Vec<Command>) {
    let Some(open) = browser.mode else { return };
    let mut keep = true;
    egui::Window::new(if open { "Open scene" } else { "Save scene as" }).collapsible(false).show(egui_ctx, |ui| {
        ui.horizontal(|ui| {
            ui.label("Folder");
            let mut text = browser.dir.display().to_string();
            if ui.text_edit_singleline(&mut text).changed() {
                browser.dir = PathBuf::from(text);
            }
            if ui.button("⬆").on_hover_text("Parent folder").clicked()
                && let Some(parent) = browser.dir.parent()
            {
                browser.dir = parent.to_path_buf();
            }
        });
        egui::ScrollArea::vertical().max_height(220.0).show(ui, |ui| match std::fs::read_dir(&browser.dir) {
            Ok(entries) => {
                let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
                entries.sort();
                for entry in entries {
                    let name = entry.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
                    if entry.is_dir() {
                        if ui.selectable_label(false, format!("📁 {name}")).clicked() {
                            browser.dir = entry;
                        }
                    } else if entry.extension().is_some_and(|e| e == "ron")
                        && ui.selectable_label(browser.name == name, format!("📄 {name}")).clicked()
                    {
                        browser.name = name;
                    }
                }
            }
            Err(e) => {
                ui.colored_label(egui::Color32::RED, format!("cannot list {}: {e}", browser.dir.display()));
            }
        });
        ui.horizontal(|ui| {
            ui.label("File");
            ui.text_edit_singleline(&mut browser.name);
        });
        ui.horizontal(|ui| {
            let path = browser.dir.join(&browser.name);
            let ok = !browser.name.trim().is_empty();
            if ui.add_enabled(ok, egui::Button::new(if open { "Open" } else { "Save" })).clicked() {
                commands.push(if open { Command::OpenScene(path) } else { Command::SaveScene(path) });
                keep = false;
            }
            if ui.button("Cancel").clicked() {
                keep = false;
            }
        });
    });
    if !keep {
        browser.mode = None;
    }
}
