"""StudioTrack application: Qt main window, engine-thread bridge, CLI and workflows."""
