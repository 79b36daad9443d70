#compdef sqscand

autoload -U is-at-least

_sqscand() {
    typeset -A opt_args
    typeset -a _arguments_options
    local ret=1

    if is-at-least 5.2; then
        _arguments_options=(-s -S -C)
    else
        _arguments_options=(-s -C)
    fi

    local context curcontext="$curcontext" state line
    _arguments "${_arguments_options[@]}" : \
'--config=[Configuration file \[default\: /etc/sqscan/sqscand.toml if it exists, else the embedded simulator configuration\]]:FILE:_files' \
'--socket=[Unix socket to listen on (overrides the file'\''s server.socket)]:PATH:_files' \
'--models-dir=[Directory of object models (overrides the file'\''s server.models_dir) \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--replay=[Serve the recorded sweeps in DIR instead of scanning (overrides the file'\''s backend)\: the daemon'\''s recordings (sweep-*.json and .pcd) and other organized PCD files with a viewpoint (and, in a build with the mcap feature, MCAP files with a ROS 2 PointCloud2)]:DIR:_files' \
'--replay-speed=[With --replay\: 1 replays at the recorded pace, 2 twice as fast, 0 as fast as asked]:FACTOR:_default' \
'--replay-loop[With --replay\: start again after the last sweep instead of stopping there]' \
'(--replay-speed)--replay-step[With --replay\: serve one recorded sweep a request, the next each time a client asks for a fresh one (\`sqscan scan\`, or a \`find\` whose newest sweep is too old), at once; the file'\''s acquisition mode becomes on_demand]' \
'--check[Run every start-up check (configuration, models, scene or calibration, serial devices) and exit]' \
'--probe[With --check\: also open the configured PTU and sensor and say what they report (the PTU is not homed or moved; an SQPF sensor is started for one profile); fails naming the device that does not answer]' \
'-h[Print help (see more with '\''--help'\'')]' \
'--help[Print help (see more with '\''--help'\'')]' \
'-V[Print version]' \
'--version[Print version]' \
&& ret=0
}

(( $+functions[_sqscand_commands] )) ||
_sqscand_commands() {
    local commands; commands=()
    _describe -t commands 'sqscand commands' commands "$@"
}

if [ "$funcstack[1]" = "_sqscand" ]; then
    _sqscand "$@"
else
    compdef _sqscand sqscand
fi
