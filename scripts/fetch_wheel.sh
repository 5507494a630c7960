# Sourced by the fetch scripts: fetch_wheel PACKAGE VERSION DIR downloads
# PACKAGE==VERSION's wheel from PyPI into DIR (pip, or curl when pip is
# missing) and unpacks it into DIR/unpacked.
fetch_wheel() {
    local package="$1" version="$2" dir="$3"
    local file="${package//-/_}"
    if command -v pip >/dev/null 2>&1 || command -v pip3 >/dev/null 2>&1; then
        "$(command -v pip || command -v pip3)" download --no-deps --quiet "$package==$version" -d "$dir"
    else
        curl -sSfL -o "$dir/$file-$version-py3-none-any.whl" \
            "https://files.pythonhosted.org/packages/py3/${package:0:1}/$package/$file-$version-py3-none-any.whl"
    fi
    mkdir -p "$dir/unpacked"
    python3 -m zipfile -e "$(ls "$dir/$file"-*.whl)" "$dir/unpacked"
}
