#compdef sqscan

autoload -U is-at-least

_sqscan() {
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
'-h[Print help]' \
'--help[Print help]' \
'-V[Print version]' \
'--version[Print version]' \
":: :_sqscan_commands" \
"*::: :->sqscan" \
&& ret=0
    case $state in
    (sqscan)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-command-$line[1]:"
        case $line[1] in
            (simulate)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--out=[Output directory (created if missing)]:DIR:_files' \
'--seed=[Seed of the sensor noise and dropout]:SEED:_default' \
'--columns=[Override the scene'\''s sensor columns (e.g. 1536 for a full-resolution sensor)]:COLUMNS:_default' \
'--json[Print one JSON object (the sweep'\''s size and the files written) instead of a line of text]' \
'-h[Print help]' \
'--help[Print help]' \
':scene -- Scene file (scenes/*.toml):_files' \
&& ret=0
;;
(show-model)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--out=[Output PLY file]:FILE.ply:_files' \
'--spacing=[Distance between surface samples (m)]:SPACING:_default' \
'--json[Print one JSON object (the model, its parts and the points written) instead of a line of text]' \
'-h[Print help]' \
'--help[Print help]' \
':model -- Model name (looked up in the models directory) or model file:_default' \
&& ret=0
;;
(info)
_arguments "${_arguments_options[@]}" : \
'--json[Print one JSON object]' \
'-h[Print help]' \
'--help[Print help]' \
':file -- Point cloud file (.ply, .pcd, or text with x y z per line):_files' \
&& ret=0
;;
(detect)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--model=[Model name (looked up in the models directory) or model file]:MODEL:_default' \
'--cloud=[Point cloud file (.pcd, .ply, text with x y z per line, or .mcap in a build with the mcap feature)]:CLOUD:_files' \
'--seed=[Seed of every random choice of the search]:SEED:_default' \
'--out=[Write the input cloud with the detected surfaces added in colour (PLY)]:DETECTED.ply:_files' \
'--max-range=[Ignore points farther than this from the viewpoint (m), e.g. a wall behind the table]:M:_default' \
'--viewpoint=[Sensor position "x,y,z" in the cloud'\''s frame \[default\: the file'\''s VIEWPOINT, else the origin\]]:X,Y,Z:_default' \
'--hypotheses=[Hypotheses for the (largest) part \[default\: the model'\''s m, else from the scene'\''s extent\]]:M:_default' \
'--trials=[RANSAC trials per hypothesis]:TRIALS:_default' \
'--repeat=[Run the detection N times on the cloud in this process and report the fastest run, for benchmarks\: the runs after the first are warm, as in the daemon. Every run must give the same answer]:N:_default' \
'--grasps=[Give every found object up to N grasps of a parallel gripper, best first, checked against the cloud (docs/GRASPS.md)]:N:_default' \
'--gripper=[The gripper'\''s settings\: a TOML file of the \[gripper\] table'\''s keys \[default\: a Robotiq 2F-85-class gripper\]]:GRIPPER.toml:_files' \
'--all[Report every accepted instance that does not overlap a better one]' \
'--keep-plane[Keep the dominant plane instead of removing it]' \
'--ignore-colour[Do not check a found object'\''s colours against the model'\''s (where both have colours)]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(learn)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'*--cloud=[Point cloud file (.pcd, .ply, or text with x y z per line); several files are sweeps of one view (organized clouds of the same size, the scene and the sensor still), learned from their per-pixel median, which cuts the noise by about the square root of their number]:CLOUD:_files' \
'--name=[Name of the learned model]:NAME:_default' \
'--parts=[Superquadric parts (1, 2 or 3)]:PARTS:_default' \
'--out=[Model file to write \[default\: MODELS_DIR/NAME.toml, unless that is the package'\''s /usr/share/sqscan/models\]]:FILE.toml:_files' \
'(--at --box --segmented)--label=[Use the points labelled as object N (mOSD labels\: label >= 20 and label / 10 == N); the table is fitted to the points labelled 1-9]:N:_default' \
'(--box --segmented)--at=[Learn the object shown by a point "x,y,z" of the cloud'\''s frame\: the connected points clear of the supporting plane (over twice its noise band) nearest to it (within 5 cm), cut from what touches it where the two meet in a concave crease]:X,Y,Z:_default' \
'(--segmented)--box=[Learn the points clear of the supporting plane (over twice its noise band) inside the box "x0,y0,z0,x1,y1,z1" (its opposite corners, in the cloud'\''s frame)]:MIN,MAX:_default' \
'--viewpoint=[Sensor position "x,y,z" \[default\: the file'\''s VIEWPOINT, else the origin\]]:X,Y,Z:_default' \
'--up=[Up direction "x,y,z" when there is no supporting plane in the cloud]:X,Y,Z:_default' \
'--max-range=[Ignore points farther than this from the viewpoint (m)]:M:_default' \
'--cost=[Residual minimised]:COST:((radial\:"Radial Euclidean distance (m)"
solina\:"Paper eq. 2 with Solina'\''s volume factor sqrt(a1 a2 a3)"
normal\:"First-order geometric distance along the surface normal (m)"))' \
'--shape=[Shapes to choose from]:SHAPE:((auto\:"A body of revolution unless the general shape fits the view clearly (5 %) better"
general\:"Any superquadric"
revolution\:"A body of revolution (for a round object whose view does not tell\: a segmented can)"))' \
'--simulate=[Instead of a cloud\: simulate the named shipped model alone on the table (fig3 rig, 2 mm noise), learn it and print the errors against the truth as JSON]:MODEL:_default' \
'--seed=[Noise seed of --simulate]:SEED:_default' \
'--sweeps=[Sweeps of the one view --simulate takes, learned from their per-pixel median]:SWEEPS:_default' \
'--rpy=[How --simulate sets the model on the table, "roll,pitch,yaw" in degrees \[default\: slender parts on their side at yaw 30, the others upright at yaw 25\]]:R,P,Y:_default' \
'--force[Replace an existing model file]' \
'--segmented[The cloud holds the object only (already segmented)\: no plane removal, no clustering; with --up it stands on the plane across up at its lowest points]' \
'--no-mirror[Do not add the visible points mirrored through the vertical axis]' \
'--silhouette[Free space just outside the points'\'' silhouette seen from the viewpoint (segmented clouds from a camera with a known position)]' \
'--no-rays[Fit the distance to the nearest surface in the final stages, not the distance along the sensor'\''s ray through each point (for a cloud whose viewpoint is not known)]' \
'-h[Print help (see more with '\''--help'\'')]' \
'--help[Print help (see more with '\''--help'\'')]' \
&& ret=0
;;
(eval)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--scene=[Scene file (scenes/*.toml)]:SCENE:_files' \
'--model=[Model name or file to detect]:MODEL:_default' \
'--trials=[Trials\: each re-simulates the sweep with new noise and searches with a new seed]:TRIALS:_default' \
'--seed=[First seed (trial k uses seed + k for both the noise and the search)]:SEED:_default' \
'--truth-object=[The scene object the model is (its pose is the truth) \[default\: the object of the same model, else the one with the model'\''s first part'\''s shape\]; for a learned model]:NAME:_default' \
'--model-in-object=[The model'\''s frame in the truth object'\''s frame, "x,y,z,qx,qy,qz,qw" (m, quaternion)\: the truth is the object'\''s pose composed with it. A learned model'\''s frame is where the learner put it on the object (its \`model_pose\` in the learning cloud, composed with the inverse of the object'\''s pose there), not the shipped model'\''s \[default\: the identity\]]:X,Y,Z,QX,QY,QZ,QW:_default' \
'--ransac-trials=[RANSAC trials per hypothesis of the detector (\`detect --trials\`) \[default\: the detector'\''s\]]:N:_default' \
'--gripper=[The gripper'\''s settings for --grasps\: a TOML file of the \[gripper\] table'\''s keys \[default\: a Robotiq 2F-85-class gripper\]]:GRIPPER.toml:_files' \
'--absent[Remove the object from the scene and count false "found" answers]' \
'--json[Print one JSON object instead of a table]' \
'--grasps[Plan a grasp for every correct detection and judge it against the truth\: returned where a brute-force sampler over the true object and scene finds a valid one, and the first grasp valid (contacts within 3 mm of the true surface and in the friction cone, the gripper 3 mm clear of the true table and every other true object)]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(eval-real)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--labels=[Labels file (JSON\: one entry a scene, its objects with class, identity, pose, support, centroid, visible, upright)]:FILE.json:_files' \
'--clouds=[Directory of the scenes'\'' clouds (SCENE.pcd for each labelled scene)]:DIR:_files' \
'--model=[Model name (looked up in the models directory) or model file]:MODEL:_default' \
'--class=[The labelled class the model should find (e.g. mug, white_bowl)]:CLASS:_default' \
'--identity=[The labelled identity (one physical object) the model should find (e.g. biscuit_tin)]:IDENTITY:_default' \
'--catalogue=[The objects'\'' sizes by identity, a markdown table with LxWxH in mm (an answer is on an object within max(5 cm, half its largest size)) \[default\: CATALOGUE.md in the labels file'\''s directory or its parent, where there is one\]]:FILE.md:_files' \
'--learned-from=[The view the model was learned from, SCENE\:GROUP\: answers there are neutral and it is not counted in recall]:SCENE:GROUP:_default' \
'--seed=[Seed of every random choice of the search]:SEED:_default' \
'--max-range=[Ignore points farther than this from the viewpoint (m)]:M:_default' \
'--gripper=[The gripper'\''s settings for --grasps\: a TOML file of the \[gripper\] table'\''s keys \[default\: a Robotiq 2F-85-class gripper\]]:GRIPPER.toml:_files' \
'--json[Print one JSON object instead of the text report]' \
'--ignore-colour[Do not check a found object'\''s colours against the model'\''s (where both have colours)]' \
'--grasps[Plan grasps for every right answer and check the first against the labels\: how many found objects get a grasp, how many first grasps sweep no point that is not the object'\''s, and of those without, how many have one that a brute-force sampler over the fit finds]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(mock)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
":: :_sqscan__subcmd__mock_commands" \
"*::: :->mock" \
&& ret=0

    case $state in
    (mock)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-mock-command-$line[1]:"
        case $line[1] in
            (ptu)
_arguments "${_arguments_options[@]}" : \
'--protocol=[The protocol the mock PTU speaks]:PROTOCOL:((powercube\:"AMTEC/Schunk PowerCube modules over RS-232"
flir\:"FLIR / Directed Perception PTU-D46 (ASCII)"))' \
'--link=[Keep a symlink to the pty here (replaced if it is a symlink)]:PATH:_files' \
'--garbage-every=[Send 1-16 random bytes before every Nth reply]:N:_default' \
'--drop-every=[Drop every Nth reply]:N:_default' \
'--corrupt-every=[Send every Nth reply with a bad checksum]:N:_default' \
'--delay-ms=[Delay every reply by this many milliseconds]:MS:_default' \
'--disconnect-after=[Close the pty (unplug) after N replies]:N:_default' \
'--replug-after-ms=[After an unplug, plug a fresh device in (new pty, same link) after this many milliseconds]:MS:_default' \
'--seed=[Seed of the garbage bytes (and, for the rig, of the sensor noise)]:SEED:_default' \
'-h[Print help (see more with '\''--help'\'')]' \
'--help[Print help (see more with '\''--help'\'')]' \
&& ret=0
;;
(rig)
_arguments "${_arguments_options[@]}" : \
'--models-dir=[Directory of object models \[default\: \$SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists\]]:DIR:_files' \
'--scene=[Scene file whose table, objects and rig the sensor sees]:SCENE:_files' \
'--protocol=[The protocol the mock PTU speaks]:PROTOCOL:((powercube\:"AMTEC/Schunk PowerCube modules over RS-232"
flir\:"FLIR / Directed Perception PTU-D46 (ASCII)"))' \
'--ptu-link=[Keep a symlink to the PTU'\''s pty here]:PATH:_files' \
'--sensor-link=[Keep a symlink to the sensor'\''s pty here]:PATH:_files' \
'--rate=[Profiles a second while acquiring]:HZ:_default' \
'--sensor=[The sensor\: an SQPF stream on a pty, or a GigE Vision line-profile camera (aravis'\''s camera emulator; needs the gige feature) on --gige-address, alongside the idle SQPF pty]:KIND:(sqpf gige)' \
'--gige-address=[Interface address the GigE Vision camera serves on (run it in a private network namespace\: see drivers/README.md)]:ADDRESS:_default' \
'--rows-per-frame=[Profiles a GigE Vision block (the camera'\''s Height)]:N:_default' \
'--camera-clock-offset=[The GigE Vision camera'\''s clock reads this much ahead of the host'\''s (s)]:SECS:_default' \
'--camera-clock-drift=[...and runs this much fast (ppm; negative\: slow)]:PPM:_default' \
'--camera-unplug-after=[Unplug the GigE Vision camera SECS after the rig starts (the emulator stops and closes its sockets)...]:SECS:_default' \
'--camera-replug-after=[...and plug a fresh one in on the same address SECS later]:SECS:_default' \
'--ptu-replug-after=[After the PTU'\''s --disconnect-after unplug, plug the same unit back in SECS later\: a new pty, the --ptu-link symlink re-pointed at it, same angles; once (it is not unplugged again). The sensor keeps streaming meanwhile]:SECS:_default' \
'--tilt-sign=[How the unit'\''s tilt is mounted\: joint tilt = SIGN x device tilt. -1 for a PTU-D46, which tilts down at negative positions (use it with calibration/sim_rig_flir.toml)]:SIGN:_default' \
'--garbage-every=[Send 1-16 random bytes before every Nth reply]:N:_default' \
'--drop-every=[Drop every Nth reply]:N:_default' \
'--corrupt-every=[Send every Nth reply with a bad checksum]:N:_default' \
'--delay-ms=[Delay every reply by this many milliseconds]:MS:_default' \
'--disconnect-after=[Close the pty (unplug) after N replies]:N:_default' \
'--replug-after-ms=[After an unplug, plug a fresh device in (new pty, same link) after this many milliseconds]:MS:_default' \
'--seed=[Seed of the garbage bytes (and, for the rig, of the sensor noise)]:SEED:_default' \
'--sensor-garbage-every=[Send 1-16 random bytes before every Nth frame]:N:_default' \
'--sensor-drop-every=[Drop every Nth frame (its sequence number is used up)]:N:_default' \
'--sensor-corrupt-every=[Send every Nth frame with a bad CRC]:N:_default' \
'--sensor-disconnect-after=[Close the sensor'\''s pty (unplug) after N frames]:N:_default' \
'-h[Print help (see more with '\''--help'\'')]' \
'--help[Print help (see more with '\''--help'\'')]' \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__mock__subcmd__help_commands" \
"*::: :->help" \
&& ret=0

    case $state in
    (help)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-mock-help-command-$line[1]:"
        case $line[1] in
            (ptu)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(rig)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
        esac
    ;;
esac
;;
(ptu)
_arguments "${_arguments_options[@]}" : \
'--device=[Serial port (or a mock'\''s pty link)]:PATH:_files' \
'--protocol=[The unit'\''s protocol]:PROTOCOL:((powercube\:"AMTEC/Schunk PowerCube modules over RS-232"
flir\:"FLIR / Directed Perception PTU-D46 (ASCII)"))' \
'--baud=[Line speed \[default\: 38400 for powercube, 9600 for flir\]]:BAUD:_default' \
'--pan-module=[PowerCube module id of the pan joint \[default\: 12\]]:PAN_MODULE:_default' \
'--tilt-module=[PowerCube module id of the tilt joint \[default\: 11\]]:TILT_MODULE:_default' \
'--pan-sign=[Pan axis sign (+1 or -1)\: joint = sign * device + offset]:PAN_SIGN:_default' \
'--pan-offset=[Pan axis offset (rad)\: the joint angle at device angle 0]:RAD:_default' \
'--tilt-sign=[Tilt axis sign (+1 or -1)\: joint = sign * device + offset (-1 for a PTU-D46 tilting down at negative positions)]:TILT_SIGN:_default' \
'--tilt-offset=[Tilt axis offset (rad)\: the joint angle at device angle 0]:RAD:_default' \
'--timeout=[Give up on a move after this many seconds]:S:_default' \
'--json[Print one JSON object (both joints'\'' angles, state words and limits, and a sweep'\''s samples summary) instead of lines of text]' \
'-h[Print help (see more with '\''--help'\'')]' \
'--help[Print help (see more with '\''--help'\'')]' \
":: :_sqscan__subcmd__ptu_commands" \
"*::: :->ptu" \
&& ret=0

    case $state in
    (ptu)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-ptu-command-$line[1]:"
        case $line[1] in
            (status)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(home)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(move)
_arguments "${_arguments_options[@]}" : \
'--pan=[Pan joint angle to reach (rad)]:RAD:_default' \
'--tilt=[Tilt joint angle to reach (rad)]:RAD:_default' \
'--speed=[Joint speed (rad/s)]:RAD_S:_default' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(sweep)
_arguments "${_arguments_options[@]}" : \
'--from=[Tilt joint angle to start from (rad); the unit moves there first]:RAD:_default' \
'--to=[Tilt joint angle to end at (rad)]:RAD:_default' \
'--speed=[Tilt speed during the sweep (rad/s)]:RAD_S:_default' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__ptu__subcmd__help_commands" \
"*::: :->help" \
&& ret=0

    case $state in
    (help)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-ptu-help-command-$line[1]:"
        case $line[1] in
            (status)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(home)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(move)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(sweep)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
        esac
    ;;
esac
;;
(sensor)
_arguments "${_arguments_options[@]}" : \
'--device=[Serial port (or a mock'\''s pty link), tcp\://HOST\:PORT for a networked sensor, or gige\://ADDRESS for a GigE Vision line-profile camera (a build with the gige feature)]:PATH:_files' \
'*--feature=[GigE Vision\: set a GenICam feature before grabbing, NAME=VALUE (true/false, an integer, a number or an enumeration entry); repeat for more, set in the order given]:NAME=VALUE:_default' \
'--rows-per-frame=[GigE Vision\: profiles a block (the camera'\''s Height) \[default\: the camera'\''s\]]:N:_default' \
'--fraction-bits=[GigE Vision\: fixed-point fraction bits of the profiles (the calibration'\''s)]:BITS:_default' \
'--baud=[Line speed]:BAUD:_default' \
'--timeout=[Give up when no profile arrives for this many seconds]:S:_default' \
'--json[Print one JSON object (grab) or one a camera (discover) instead of text]' \
'-h[Print help]' \
'--help[Print help]' \
":: :_sqscan__subcmd__sensor_commands" \
"*::: :->sensor" \
&& ret=0

    case $state in
    (sensor)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-sensor-command-$line[1]:"
        case $line[1] in
            (grab)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
'::count -- Profiles to receive:_default' \
&& ret=0
;;
(discover)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__sensor__subcmd__help_commands" \
"*::: :->help" \
&& ret=0

    case $state in
    (help)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-sensor-help-command-$line[1]:"
        case $line[1] in
            (grab)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(discover)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
        esac
    ;;
esac
;;
(find)
_arguments "${_arguments_options[@]}" : \
'--max-age=[Accept a sweep up to this old (s); else wait for the next one]:S:_default' \
'--timeout=[Give up after this long (s)]:S:_default' \
'--grasps=[Up to N grasps of the daemon'\''s gripper for each found instance, best first]:N:_default' \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--all[Every instance, not only the best]' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
':object -- Object (model) name, e.g. cup:_default' \
&& ret=0
;;
(scan)
_arguments "${_arguments_options[@]}" : \
'--timeout=[Give up after this long (s)]:S:_default' \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(cloud)
_arguments "${_arguments_options[@]}" : \
'--out=[Write the sweep'\''s points here (a binary PCD file, organized, with the sensor'\''s viewpoint)]:FILE.pcd:_files' \
'--max-age=[Accept a sweep up to this old (s); else wait for the next one]:S:_default' \
'--timeout=[Give up after this long (s)]:S:_default' \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(watch)
_arguments "${_arguments_options[@]}" : \
'--count=[Stop after this many detection messages (default\: until interrupted)]:N:_default' \
'--grasps=[Up to N grasps of the daemon'\''s gripper for each found instance, best first]:N:_default' \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
'*::objects -- Objects to report on every sweep:_default' \
&& ret=0
;;
(status)
_arguments "${_arguments_options[@]}" : \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(models)
_arguments "${_arguments_options[@]}" : \
'--socket=[The daemon'\''s socket, or tcp\://HOST\:PORT for a daemon listening on TCP (\[server\] tcp) \[default\: \$SQSCAN_SOCKET, else \$XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock\: the first that exists\]]:PATH:_files' \
'--json[Print the daemon'\''s JSON replies as they are, one a line]' \
'-h[Print help]' \
'--help[Print help]' \
&& ret=0
;;
(completions)
_arguments "${_arguments_options[@]}" : \
'--daemon[The script for sqscand instead of sqscan]' \
'-h[Print help]' \
'--help[Print help]' \
':shell -- The shell\: e.g. `sqscan completions bash > ~/.local/share/bash-completion/completions/sqscan`:(bash elvish fish powershell zsh)' \
&& ret=0
;;
(man)
_arguments "${_arguments_options[@]}" : \
'-h[Print help]' \
'--help[Print help]' \
':out -- Directory to write sqscan.1, sqscan-*.1 and sqscand.8 into (created if missing):_files' \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__help_commands" \
"*::: :->help" \
&& ret=0

    case $state in
    (help)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-help-command-$line[1]:"
        case $line[1] in
            (simulate)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(show-model)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(info)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(detect)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(learn)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(eval)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(eval-real)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(mock)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__help__subcmd__mock_commands" \
"*::: :->mock" \
&& ret=0

    case $state in
    (mock)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-help-mock-command-$line[1]:"
        case $line[1] in
            (ptu)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(rig)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
(ptu)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__help__subcmd__ptu_commands" \
"*::: :->ptu" \
&& ret=0

    case $state in
    (ptu)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-help-ptu-command-$line[1]:"
        case $line[1] in
            (status)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(home)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(move)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(sweep)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
(sensor)
_arguments "${_arguments_options[@]}" : \
":: :_sqscan__subcmd__help__subcmd__sensor_commands" \
"*::: :->sensor" \
&& ret=0

    case $state in
    (sensor)
        words=($line[1] "${words[@]}")
        (( CURRENT += 1 ))
        curcontext="${curcontext%:*:*}:sqscan-help-sensor-command-$line[1]:"
        case $line[1] in
            (grab)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(discover)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
(find)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(scan)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(cloud)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(watch)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(status)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(models)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(completions)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(man)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
(help)
_arguments "${_arguments_options[@]}" : \
&& ret=0
;;
        esac
    ;;
esac
;;
        esac
    ;;
esac
}

(( $+functions[_sqscan_commands] )) ||
_sqscan_commands() {
    local commands; commands=(
'simulate:Simulate one sweep of a scene\: writes cloud.ply, cloud.pcd, range.png and truth.json' \
'show-model:Sample a model'\''s surface into a PLY file (one colour a part)' \
'info:Print a point cloud file'\''s point count, finite points, organization and bounding box' \
'detect:Find an object in a point cloud file; prints one JSON object' \
'learn:Learn a model by showing the object\: recover its superquadric from one scan' \
'eval:Measure detection rate, false "found" rate, time and pose error on simulated sweeps' \
'eval-real:Measure the detector on real scans labelled by object class\: recall, false answers, time' \
'mock:Run mock devices on pseudo-terminals (use their paths like hardware)' \
'ptu:Bring-up tool for a pan-tilt unit\: status, home, move, sweep' \
'sensor:Bring-up tool for a profile sensor\: grab profiles and print their statistics' \
'find:Ask the daemon where an object is (from a recent sweep, or the next one)' \
'scan:Ask the daemon for a sweep now; prints it when complete' \
'cloud:Fetch a recent sweep'\''s points from the daemon into a PCD file' \
'watch:Print every sweep'\''s detections of the given objects until interrupted' \
'status:The daemon'\''s devices, last sweep, rates and faults' \
'models:The objects the daemon knows' \
'completions:Print a shell completion script for sqscan (or, with --daemon, sqscand)' \
'man:Write the manual pages of sqscan (one a subcommand) and sqscand into a directory' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__cloud_commands] )) ||
_sqscan__subcmd__cloud_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan cloud commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__completions_commands] )) ||
_sqscan__subcmd__completions_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan completions commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__detect_commands] )) ||
_sqscan__subcmd__detect_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan detect commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__eval_commands] )) ||
_sqscan__subcmd__eval_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan eval commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__eval-real_commands] )) ||
_sqscan__subcmd__eval-real_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan eval-real commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__find_commands] )) ||
_sqscan__subcmd__find_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan find commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help_commands] )) ||
_sqscan__subcmd__help_commands() {
    local commands; commands=(
'simulate:Simulate one sweep of a scene\: writes cloud.ply, cloud.pcd, range.png and truth.json' \
'show-model:Sample a model'\''s surface into a PLY file (one colour a part)' \
'info:Print a point cloud file'\''s point count, finite points, organization and bounding box' \
'detect:Find an object in a point cloud file; prints one JSON object' \
'learn:Learn a model by showing the object\: recover its superquadric from one scan' \
'eval:Measure detection rate, false "found" rate, time and pose error on simulated sweeps' \
'eval-real:Measure the detector on real scans labelled by object class\: recall, false answers, time' \
'mock:Run mock devices on pseudo-terminals (use their paths like hardware)' \
'ptu:Bring-up tool for a pan-tilt unit\: status, home, move, sweep' \
'sensor:Bring-up tool for a profile sensor\: grab profiles and print their statistics' \
'find:Ask the daemon where an object is (from a recent sweep, or the next one)' \
'scan:Ask the daemon for a sweep now; prints it when complete' \
'cloud:Fetch a recent sweep'\''s points from the daemon into a PCD file' \
'watch:Print every sweep'\''s detections of the given objects until interrupted' \
'status:The daemon'\''s devices, last sweep, rates and faults' \
'models:The objects the daemon knows' \
'completions:Print a shell completion script for sqscan (or, with --daemon, sqscand)' \
'man:Write the manual pages of sqscan (one a subcommand) and sqscand into a directory' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__cloud_commands] )) ||
_sqscan__subcmd__help__subcmd__cloud_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help cloud commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__completions_commands] )) ||
_sqscan__subcmd__help__subcmd__completions_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help completions commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__detect_commands] )) ||
_sqscan__subcmd__help__subcmd__detect_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help detect commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__eval_commands] )) ||
_sqscan__subcmd__help__subcmd__eval_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help eval commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__eval-real_commands] )) ||
_sqscan__subcmd__help__subcmd__eval-real_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help eval-real commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__find_commands] )) ||
_sqscan__subcmd__help__subcmd__find_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help find commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__help_commands] )) ||
_sqscan__subcmd__help__subcmd__help_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__info_commands] )) ||
_sqscan__subcmd__help__subcmd__info_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help info commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__learn_commands] )) ||
_sqscan__subcmd__help__subcmd__learn_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help learn commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__man_commands] )) ||
_sqscan__subcmd__help__subcmd__man_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help man commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__mock_commands] )) ||
_sqscan__subcmd__help__subcmd__mock_commands() {
    local commands; commands=(
'ptu:Run a mock pan-tilt unit on a pty until interrupted' \
'rig:Run the mock scanning rig until interrupted\: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU'\''s current angles' \
    )
    _describe -t commands 'sqscan help mock commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__mock__subcmd__ptu_commands] )) ||
_sqscan__subcmd__help__subcmd__mock__subcmd__ptu_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help mock ptu commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__mock__subcmd__rig_commands] )) ||
_sqscan__subcmd__help__subcmd__mock__subcmd__rig_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help mock rig commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__models_commands] )) ||
_sqscan__subcmd__help__subcmd__models_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help models commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__ptu_commands] )) ||
_sqscan__subcmd__help__subcmd__ptu_commands() {
    local commands; commands=(
'status:Print both joints'\'' angles, state words and limits' \
'home:Reset and home (PowerCube\: wait for HOME_OK; PTU-D46\: its recalibrating reset)' \
'move:Move to an absolute pose (an axis not given stays where it is) and wait until reached' \
'sweep:Tilt from one angle to another at a constant speed, sampling the position on the way' \
    )
    _describe -t commands 'sqscan help ptu commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__ptu__subcmd__home_commands] )) ||
_sqscan__subcmd__help__subcmd__ptu__subcmd__home_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help ptu home commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__ptu__subcmd__move_commands] )) ||
_sqscan__subcmd__help__subcmd__ptu__subcmd__move_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help ptu move commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__ptu__subcmd__status_commands] )) ||
_sqscan__subcmd__help__subcmd__ptu__subcmd__status_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help ptu status commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__ptu__subcmd__sweep_commands] )) ||
_sqscan__subcmd__help__subcmd__ptu__subcmd__sweep_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help ptu sweep commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__scan_commands] )) ||
_sqscan__subcmd__help__subcmd__scan_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help scan commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__sensor_commands] )) ||
_sqscan__subcmd__help__subcmd__sensor_commands() {
    local commands; commands=(
'grab:Start acquisition, receive N profiles, stop, and print statistics' \
'discover:List the GigE Vision cameras that answer a discovery broadcast on this host'\''s networks (give --device gige\://ANY; a build with the gige feature)' \
    )
    _describe -t commands 'sqscan help sensor commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__sensor__subcmd__discover_commands] )) ||
_sqscan__subcmd__help__subcmd__sensor__subcmd__discover_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help sensor discover commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__sensor__subcmd__grab_commands] )) ||
_sqscan__subcmd__help__subcmd__sensor__subcmd__grab_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help sensor grab commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__show-model_commands] )) ||
_sqscan__subcmd__help__subcmd__show-model_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help show-model commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__simulate_commands] )) ||
_sqscan__subcmd__help__subcmd__simulate_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help simulate commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__status_commands] )) ||
_sqscan__subcmd__help__subcmd__status_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help status commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__help__subcmd__watch_commands] )) ||
_sqscan__subcmd__help__subcmd__watch_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan help watch commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__info_commands] )) ||
_sqscan__subcmd__info_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan info commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__learn_commands] )) ||
_sqscan__subcmd__learn_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan learn commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__man_commands] )) ||
_sqscan__subcmd__man_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan man commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock_commands] )) ||
_sqscan__subcmd__mock_commands() {
    local commands; commands=(
'ptu:Run a mock pan-tilt unit on a pty until interrupted' \
'rig:Run the mock scanning rig until interrupted\: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU'\''s current angles' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan mock commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__help_commands] )) ||
_sqscan__subcmd__mock__subcmd__help_commands() {
    local commands; commands=(
'ptu:Run a mock pan-tilt unit on a pty until interrupted' \
'rig:Run the mock scanning rig until interrupted\: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU'\''s current angles' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan mock help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__help__subcmd__help_commands] )) ||
_sqscan__subcmd__mock__subcmd__help__subcmd__help_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan mock help help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__help__subcmd__ptu_commands] )) ||
_sqscan__subcmd__mock__subcmd__help__subcmd__ptu_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan mock help ptu commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__help__subcmd__rig_commands] )) ||
_sqscan__subcmd__mock__subcmd__help__subcmd__rig_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan mock help rig commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__ptu_commands] )) ||
_sqscan__subcmd__mock__subcmd__ptu_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan mock ptu commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__mock__subcmd__rig_commands] )) ||
_sqscan__subcmd__mock__subcmd__rig_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan mock rig commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__models_commands] )) ||
_sqscan__subcmd__models_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan models commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu_commands] )) ||
_sqscan__subcmd__ptu_commands() {
    local commands; commands=(
'status:Print both joints'\'' angles, state words and limits' \
'home:Reset and home (PowerCube\: wait for HOME_OK; PTU-D46\: its recalibrating reset)' \
'move:Move to an absolute pose (an axis not given stays where it is) and wait until reached' \
'sweep:Tilt from one angle to another at a constant speed, sampling the position on the way' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan ptu commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help_commands() {
    local commands; commands=(
'status:Print both joints'\'' angles, state words and limits' \
'home:Reset and home (PowerCube\: wait for HOME_OK; PTU-D46\: its recalibrating reset)' \
'move:Move to an absolute pose (an axis not given stays where it is) and wait until reached' \
'sweep:Tilt from one angle to another at a constant speed, sampling the position on the way' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan ptu help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help__subcmd__help_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help__subcmd__help_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu help help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help__subcmd__home_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help__subcmd__home_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu help home commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help__subcmd__move_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help__subcmd__move_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu help move commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help__subcmd__status_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help__subcmd__status_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu help status commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__help__subcmd__sweep_commands] )) ||
_sqscan__subcmd__ptu__subcmd__help__subcmd__sweep_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu help sweep commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__home_commands] )) ||
_sqscan__subcmd__ptu__subcmd__home_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu home commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__move_commands] )) ||
_sqscan__subcmd__ptu__subcmd__move_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu move commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__status_commands] )) ||
_sqscan__subcmd__ptu__subcmd__status_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu status commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__ptu__subcmd__sweep_commands] )) ||
_sqscan__subcmd__ptu__subcmd__sweep_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan ptu sweep commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__scan_commands] )) ||
_sqscan__subcmd__scan_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan scan commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor_commands] )) ||
_sqscan__subcmd__sensor_commands() {
    local commands; commands=(
'grab:Start acquisition, receive N profiles, stop, and print statistics' \
'discover:List the GigE Vision cameras that answer a discovery broadcast on this host'\''s networks (give --device gige\://ANY; a build with the gige feature)' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan sensor commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__discover_commands] )) ||
_sqscan__subcmd__sensor__subcmd__discover_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan sensor discover commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__grab_commands] )) ||
_sqscan__subcmd__sensor__subcmd__grab_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan sensor grab commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__help_commands] )) ||
_sqscan__subcmd__sensor__subcmd__help_commands() {
    local commands; commands=(
'grab:Start acquisition, receive N profiles, stop, and print statistics' \
'discover:List the GigE Vision cameras that answer a discovery broadcast on this host'\''s networks (give --device gige\://ANY; a build with the gige feature)' \
'help:Print this message or the help of the given subcommand(s)' \
    )
    _describe -t commands 'sqscan sensor help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__help__subcmd__discover_commands] )) ||
_sqscan__subcmd__sensor__subcmd__help__subcmd__discover_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan sensor help discover commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__help__subcmd__grab_commands] )) ||
_sqscan__subcmd__sensor__subcmd__help__subcmd__grab_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan sensor help grab commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__sensor__subcmd__help__subcmd__help_commands] )) ||
_sqscan__subcmd__sensor__subcmd__help__subcmd__help_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan sensor help help commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__show-model_commands] )) ||
_sqscan__subcmd__show-model_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan show-model commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__simulate_commands] )) ||
_sqscan__subcmd__simulate_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan simulate commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__status_commands] )) ||
_sqscan__subcmd__status_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan status commands' commands "$@"
}
(( $+functions[_sqscan__subcmd__watch_commands] )) ||
_sqscan__subcmd__watch_commands() {
    local commands; commands=()
    _describe -t commands 'sqscan watch commands' commands "$@"
}

if [ "$funcstack[1]" = "_sqscan" ]; then
    _sqscan "$@"
else
    compdef _sqscan sqscan
fi
