//! OBJ and GLB writers.
