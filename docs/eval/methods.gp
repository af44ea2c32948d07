# methods.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot methods.gp
if (!exists("outfile")) outfile = "methods.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "Robustness vs backliers on the thesis's scene (4.1)\n(normal within 5 deg and offset within 0.1 m of the true wall)"
set xlabel "rho_b of the data"
set ylabel "robustness (eq. 3.7)"
set yrange [-0.05:1.05]
set grid
set key outside right
plot "methods.csv" skip 1 using 1:(strcol(2) eq "ransac" ? $5 : NaN) with linespoints lw 2 title "ransac", "" skip 1 using 1:(strcol(2) eq "msac" ? $5 : NaN) with linespoints lw 2 title "msac", "" skip 1 using 1:(strcol(2) eq "bsf" ? $5 : NaN) with linespoints lw 2 title "bsf", "" skip 1 using 1:(strcol(2) eq "binomial" ? $5 : NaN) with linespoints lw 2 title "binomial", "" skip 1 using 1:(strcol(2) eq "pcl" ? $5 : NaN) with linespoints lw 2 title "pcl", "" skip 1 using 1:(strcol(2) eq "open3d" ? $5 : NaN) with linespoints lw 2 title "open3d"
