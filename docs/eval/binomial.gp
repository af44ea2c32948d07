# binomial.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot binomial.gp
if (!exists("outfile")) outfile = "binomial.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "B-RANSAC (eq. 3.4): rho set vs the data's rho_b (fig. 4.3)\n(normal within 5 deg and offset within 0.1 m of the true wall)"
set xlabel "rho_b set in the algorithm"
set ylabel "rho_b of the data"
set palette gray
set cbrange [0:1]
set cblabel "robustness (eq. 3.7)"
set xrange [0.025:0.975]
set yrange [-0.025:0.925]
set tics out
unset key
plot "binomial.csv" skip 1 using 1:2:(0.025):(0.025):5 with boxxyerror fs solid 1.0 noborder lc palette
