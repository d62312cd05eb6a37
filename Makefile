# Thin wrapper over ./run (which installs what it needs). BPY_VERSION=4.5.15 make test, etc.
.PHONY: demo test test-physics bench build
demo test test-physics bench build:
	./run $@
