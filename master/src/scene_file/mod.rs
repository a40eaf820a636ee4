//! Scene files: TOML scenes placing OBJ/glTF meshes, lights and devices, loaded into a validated `Showcase`.
