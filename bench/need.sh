# Checks for the benchmarks' external tools, sourced by bench/*.sh: each stops the benchmark
# with one line saying what to install, before any work.

# need_python SCRIPT PACKAGE... — sets `python` to $PYTHON (default python3) if it imports
# every pip PACKAGE (pillow is imported as PIL), else exits naming a venv that has them.
need_python() {
    local script=$1 modules
    shift
    python=${PYTHON:-python3}
    modules=$(echo "$@" | sed 's/\bpillow\b/PIL/; s/ /, /g')
    "$python" -c "import $modules" 2>/dev/null && return
    echo "bench/$script needs $*: python3 -m venv /tmp/venv && /tmp/venv/bin/pip install $*," \
        "then PYTHON=/tmp/venv/bin/python bash bench/$script" >&2
    exit 1
}

# need_openjpeg SCRIPT — exits unless opj_compress and opj_decompress are on the path.
need_openjpeg() {
    command -v opj_compress >/dev/null && command -v opj_decompress >/dev/null && return
    echo "bench/$1 needs OpenJPEG: apt-get install -y libopenjp2-tools" >&2
    exit 1
}
