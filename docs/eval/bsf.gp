# bsf.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot bsf.gp
if (!exists("outfile")) outfile = "bsf.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "BSF-RANSAC (eq. 3.1): beta vs the data's rho_b (fig. 4.2)\n(normal within 5 deg and offset within 0.1 m of the true wall)"
set xlabel "beta (backlier weight)"
set ylabel "rho_b of the data"
set palette gray
set cbrange [0:1]
set cblabel "robustness (eq. 3.7)"
set xrange [-0.05:2.05]
set yrange [-0.025:0.925]
set tics out
unset key
plot "bsf.csv" skip 1 using 1:2:(0.05):(0.025):5 with boxxyerror fs solid 1.0 noborder lc palette
