"""The dataset writer: the HDF5 streaming writer, the one schema room, the direct chunk path."""
